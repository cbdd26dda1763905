# FindSuiteSparse: Debian 12 ships SuiteSparse 5.12 without CMake package
# files, so we locate the headers and libraries ourselves.
#
# Components: CHOLMOD CCOLAMD COLAMD AMD CAMD (SuiteSparse_config is always found).
# Imported targets: SuiteSparse::<Component> and SuiteSparse::config.
# Result variables: SuiteSparse_FOUND, SuiteSparse_INCLUDE_DIR.

find_path(SuiteSparse_INCLUDE_DIR NAMES SuiteSparse_config.h
  PATH_SUFFIXES suitesparse)
find_library(SuiteSparse_config_LIBRARY NAMES suitesparseconfig)

set(_ss_deps_CHOLMOD AMD CAMD COLAMD CCOLAMD)
set(_ss_components ${SuiteSparse_FIND_COMPONENTS})
foreach(_c IN LISTS SuiteSparse_FIND_COMPONENTS)
  list(APPEND _ss_components ${_ss_deps_${_c}})
endforeach()
list(REMOVE_DUPLICATES _ss_components)

set(_ss_header_CHOLMOD cholmod.h)
set(_ss_header_CCOLAMD ccolamd.h)
set(_ss_header_COLAMD colamd.h)
set(_ss_header_AMD amd.h)
set(_ss_header_CAMD camd.h)

foreach(_c IN LISTS _ss_components)
  string(TOLOWER ${_c} _lc)
  find_library(SuiteSparse_${_c}_LIBRARY NAMES ${_lc})
  if(SuiteSparse_${_c}_LIBRARY AND SuiteSparse_INCLUDE_DIR
     AND EXISTS "${SuiteSparse_INCLUDE_DIR}/${_ss_header_${_c}}")
    set(SuiteSparse_${_c}_FOUND TRUE)
  else()
    set(SuiteSparse_${_c}_FOUND FALSE)
  endif()
endforeach()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(SuiteSparse
  REQUIRED_VARS SuiteSparse_INCLUDE_DIR SuiteSparse_config_LIBRARY
  HANDLE_COMPONENTS)

if(SuiteSparse_FOUND AND NOT TARGET SuiteSparse::config)
  add_library(SuiteSparse::config UNKNOWN IMPORTED)
  set_target_properties(SuiteSparse::config PROPERTIES
    IMPORTED_LOCATION "${SuiteSparse_config_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${SuiteSparse_INCLUDE_DIR}")
  foreach(_c IN LISTS _ss_components)
    if(SuiteSparse_${_c}_FOUND AND NOT TARGET SuiteSparse::${_c})
      add_library(SuiteSparse::${_c} UNKNOWN IMPORTED)
      set_target_properties(SuiteSparse::${_c} PROPERTIES
        IMPORTED_LOCATION "${SuiteSparse_${_c}_LIBRARY}"
        INTERFACE_INCLUDE_DIRECTORIES "${SuiteSparse_INCLUDE_DIR}")
      set(_links SuiteSparse::config)
      foreach(_d IN LISTS _ss_deps_${_c})
        if(SuiteSparse_${_d}_FOUND)
          list(APPEND _links SuiteSparse::${_d})
        endif()
      endforeach()
      set_property(TARGET SuiteSparse::${_c} PROPERTY INTERFACE_LINK_LIBRARIES ${_links})
    endif()
  endforeach()
endif()
mark_as_advanced(SuiteSparse_INCLUDE_DIR SuiteSparse_config_LIBRARY)
