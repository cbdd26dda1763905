# Cross-compiling rilo for a Debian arm64 (aarch64) board on a Debian amd64
# host, with the board's libraries installed as multiarch packages
# (libfoo-dev:arm64: libraries and CMake package files in
# /usr/lib/aarch64-linux-gnu, headers in /usr/include shared with the host).
# scripts/cross-build-aarch64.sh installs them and drives the build:
#
#   cmake -S . -B build-aarch64 -G Ninja \
#     -DCMAKE_TOOLCHAIN_FILE=cmake/toolchains/aarch64-linux-gnu.cmake
#
# As Debian's own cross builds do, no sysroot: CMAKE_LIBRARY_ARCHITECTURE
# makes find_library / find_package look in /usr/lib/aarch64-linux-gnu (never
# in the host's /usr/lib/x86_64-linux-gnu); programs (idlc, pkg-config) are
# the host's. Target executables run under qemu-user through
# CMAKE_CROSSCOMPILING_EMULATOR (ctest, gtest_discover_tests) when
# qemu-aarch64 is installed.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(RILO_CROSS_TRIPLE aarch64-linux-gnu)

set(CMAKE_C_COMPILER ${RILO_CROSS_TRIPLE}-gcc)
set(CMAKE_CXX_COMPILER ${RILO_CROSS_TRIPLE}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${RILO_CROSS_TRIPLE})

# pkg-config (libgpiod, libsystemd): the target's .pc files only.
if(EXISTS /usr/bin/${RILO_CROSS_TRIPLE}-pkg-config)
  set(PKG_CONFIG_EXECUTABLE /usr/bin/${RILO_CROSS_TRIPLE}-pkg-config CACHE FILEPATH "pkg-config for the target")
else()
  set(ENV{PKG_CONFIG_LIBDIR} "/usr/lib/${RILO_CROSS_TRIPLE}/pkgconfig:/usr/share/pkgconfig")
  set(ENV{PKG_CONFIG_PATH} "")
endif()

# Tests and gtest discovery run under qemu-user with the cross toolchain's
# loader and libc (/usr/aarch64-linux-gnu); the multiarch libraries in
# /usr/lib/aarch64-linux-gnu are found through that loader's default paths.
find_program(RILO_QEMU_AARCH64 NAMES qemu-aarch64 qemu-aarch64-static)
if(RILO_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${RILO_QEMU_AARCH64} -L /usr/${RILO_CROSS_TRIPLE})
endif()
