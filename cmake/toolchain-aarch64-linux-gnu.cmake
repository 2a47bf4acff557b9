# Cross-build for 64-bit ARM Linux (AArch64) with Debian's cross compiler (g++-aarch64-linux-gnu) and the arm64
# libraries of a multiarch installation (dpkg --add-architecture arm64; headers in /usr/include, libraries in
# /usr/lib/aarch64-linux-gnu). scripts/test-arm64.sh sets everything up and runs the tests under qemu-aarch64.
#
#   cmake -S . -B build-arm64 -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-aarch64-linux-gnu.cmake
#
# EGOPD_ARM64_EXTRA_ROOT (optional): a directory holding extracted arm64 packages (usr/lib/aarch64-linux-gnu, ...)
# for libraries whose arm64 development packages cannot be installed beside the amd64 ones (OpenCV's): searched by
# find_package, passed to the linker for indirect dependencies and to the emulated loader (LD_LIBRARY_PATH).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

# Programs (qemu, bash) are the build machine's; libraries and packages only of the target architecture.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)

set(EGOPD_ARM64_EXTRA_ROOT "" CACHE PATH "Extracted arm64 packages for libraries not installable by multiarch")
set(_egopd_libdirs "")
if(EGOPD_ARM64_EXTRA_ROOT)
  list(APPEND CMAKE_PREFIX_PATH "${EGOPD_ARM64_EXTRA_ROOT}/usr")
  foreach(d usr/lib/aarch64-linux-gnu lib/aarch64-linux-gnu usr/lib usr/lib/aarch64-linux-gnu/blas
            usr/lib/aarch64-linux-gnu/lapack)
    if(EXISTS "${EGOPD_ARM64_EXTRA_ROOT}/${d}")
      list(APPEND _egopd_libdirs "${EGOPD_ARM64_EXTRA_ROOT}/${d}")
      string(APPEND CMAKE_EXE_LINKER_FLAGS_INIT " -Wl,-rpath-link,${EGOPD_ARM64_EXTRA_ROOT}/${d}")
      string(APPEND CMAKE_SHARED_LINKER_FLAGS_INIT " -Wl,-rpath-link,${EGOPD_ARM64_EXTRA_ROOT}/${d}")
    endif()
  endforeach()
endif()

# Test programs run under user-mode emulation (ctest and gtest_discover_tests prefix them with this).
find_program(EGOPD_QEMU_AARCH64 qemu-aarch64 REQUIRED)
set(CMAKE_CROSSCOMPILING_EMULATOR "${EGOPD_QEMU_AARCH64}")
if(_egopd_libdirs)
  list(JOIN _egopd_libdirs ":" _egopd_ld_path)
  list(APPEND CMAKE_CROSSCOMPILING_EMULATOR -E "LD_LIBRARY_PATH=${_egopd_ld_path}")
endif()
