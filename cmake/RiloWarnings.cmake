# rilo_target_warnings(<target>): strict warnings for our own code only, so
# third-party headers (included as SYSTEM) never break the build.
function(rilo_target_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow
    -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Woverloaded-virtual
    -Wnull-dereference -Wdouble-promotion -Wformat=2 -Wimplicit-fallthrough)
  if(RILO_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
