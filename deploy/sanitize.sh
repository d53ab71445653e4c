#!/usr/bin/env bash
# Builds RVEHub with AddressSanitizer, UndefinedBehaviorSanitizer and libstdc++'s
# assertions into ${BUILD_DIR:-build-sanitize} and runs the tests there (any ctest
# arguments pass through, e.g. -R Fuzz). A memory error, undefined behaviour (signed
# overflow, a null pointer to memcmp, ...), a leak or an index past a container's size
# fails the test that met it. Installs the packages first, as test.sh does. Not part of
# CI: the build takes about 20 min and the tests about 7 min on 2 cores. For a long fuzz
# run under the sanitizers:
#   RVEHUB_FUZZ_ITERATIONS=100000 RVEHUB_FUZZ_SEED=$RANDOM build-sanitize/tests/fuzz_test
set -euo pipefail
cd "$(dirname "$0")/.."

bash deploy/install_deps.sh

BUILD_DIR="${BUILD_DIR:-build-sanitize}"
# GCC leaves float-cast-overflow (a NaN or huge double converted to an integer, which
# hostile input could reach) out of "undefined".
flags="-fsanitize=address,undefined,float-cast-overflow -fno-omit-frame-pointer"
flags+=" -fno-sanitize-recover=undefined,float-cast-overflow"
# libstdc++'s checks: an index past size() but within capacity(), which ASan cannot see.
cxx_checks="-D_GLIBCXX_ASSERTIONS"
# GCC 12's -Wmaybe-uninitialized misfires inside std::regex and std::function once the
# sanitizers instrument them; the Release build keeps the warning as an error.
cmake -S . -B "${BUILD_DIR}" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS="${flags} ${cxx_checks} -Wno-maybe-uninitialized" \
  -DCMAKE_EXE_LINKER_FLAGS="${flags}" -DCMAKE_SHARED_LINKER_FLAGS="${flags}"
cmake --build "${BUILD_DIR}" -j"$(nproc)"

# Leaks are checked too, less what libraries keep (deploy/lsan.supp); print_suppressions=0
# keeps LeakSanitizer's summary out of the stderr that some tests read.
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=${PWD}/deploy/lsan.supp:print_suppressions=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
ctest --test-dir "${BUILD_DIR}" --output-on-failure -j2 --timeout 1500 "$@"
