# -DRILO_SANITIZE=ON: AddressSanitizer + UndefinedBehaviorSanitizer on every
# target (use with CMAKE_BUILD_TYPE=RelWithDebInfo or Debug).
if(RILO_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  add_link_options(-fsanitize=address,undefined)
  add_compile_definitions(RILO_NO_TARGET_CLONES)  # ifunc resolvers run before the sanitizer's runtime
endif()
# -DRILO_FUZZ=ON: libFuzzer's coverage instrumentation on every target (the
# fuzz executables add its main; tests/fuzz/CMakeLists.txt).
if(RILO_FUZZ)
  add_compile_options(-fsanitize=fuzzer-no-link)
endif()

# -DRILO_TSAN=ON: ThreadSanitizer on every target, for the lock-free runtime
# (queues, seqlock, heartbeat). Its runtime cannot be combined with ASan's.
option(RILO_TSAN "Build with ThreadSanitizer (exclusive with RILO_SANITIZE)" OFF)
if(RILO_TSAN)
  if(RILO_SANITIZE)
    message(FATAL_ERROR "RILO_TSAN and RILO_SANITIZE are mutually exclusive: use separate build directories")
  endif()
  add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
  add_link_options(-fsanitize=thread)
  add_compile_definitions(RILO_NO_TARGET_CLONES)  # ifunc resolvers run before the sanitizer's runtime
endif()
