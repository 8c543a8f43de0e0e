# aerorelay codegen: cross-compile the tree for a 64-bit ARM companion computer (Debian/Ubuntu: apt-get install
# gcc-aarch64-linux-gnu). HPIPM_PREFIX / BLASFEO_PREFIX must then name HPIPM and BLASFEO built for aarch64 (their CMake
# projects, or an acados install on the drone) to link the programs; the library builds without them:
#   cmake -S . -B build-arm -DCMAKE_TOOLCHAIN_FILE=cmake/aarch64-linux-gnu.cmake -DHPIPM_PREFIX=/opt/aarch64/hpipm
#   cmake --build build-arm --target aerorelay_controller
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
