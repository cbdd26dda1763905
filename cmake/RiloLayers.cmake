# The layers, enforced by the build (docs/architecture.md "Layers").
#
# rilo_public_folders(<target> <PUBLIC|INTERFACE> <path>...)
#   A library's public include directory holds its own folders and nothing
#   else: build/include/<target>/ gets a link to each <path> (a folder or one
#   header, given from the repository root), named as the code includes it:
#   service/estimation -> estimation/, hal/recording -> hal/recording/. A
#   library therefore compiles an include of another layer only when it links
#   that layer, and what it links is written in its CMakeLists.txt.
function(rilo_public_folders target scope)
  set(root ${PROJECT_BINARY_DIR}/include/${target})
  # Links of folders the target no longer lists go (file(REMOVE) takes the
  # link, never what it points to; the glob does not follow links).
  set(wanted "")
  foreach(path IN LISTS ARGN)
    string(REGEX REPLACE "^service/" "" name "${path}")
    list(APPEND wanted "${root}/${name}")
  endforeach()
  file(GLOB_RECURSE existing LIST_DIRECTORIES true "${root}/*")
  foreach(entry IN LISTS existing)
    if(IS_SYMLINK "${entry}" AND NOT entry IN_LIST wanted)
      file(REMOVE "${entry}")
    endif()
  endforeach()
  foreach(path IN LISTS ARGN)
    string(REGEX REPLACE "^service/" "" name "${path}")
    get_filename_component(parent "${root}/${name}" DIRECTORY)
    file(MAKE_DIRECTORY "${parent}")
    file(REMOVE "${root}/${name}")
    file(CREATE_LINK "${PROJECT_SOURCE_DIR}/${path}" "${root}/${name}" SYMBOLIC)
  endforeach()
  target_include_directories(${target} ${scope} ${root})
endfunction()

# Every build checks that production code includes only its own and lower
# layers (cmake/check_layers.cmake; a second-long scan of the sources).
add_custom_target(rilo_layers ALL
  COMMAND ${CMAKE_COMMAND} -DSOURCE_DIR=${PROJECT_SOURCE_DIR} -P ${PROJECT_SOURCE_DIR}/cmake/check_layers.cmake
  COMMENT "Checking that every layer includes only itself and the layers below"
  VERBATIM)
