// Sizes and parameters of long or measuring test runs from the environment
// (RVEHUB_FUZZ_ITERATIONS, RVEHUB_CASE_FUZZ_SEED, RVEHUB_PRANDTL_PHI, ...):
// unset or empty gives the test's own value.
#ifndef RVEHUB_TESTS_SUPPORT_ENV_UTIL_H_
#define RVEHUB_TESTS_SUPPORT_ENV_UTIL_H_

#include <cstdint>
#include <cstdlib>

namespace rvehub::testing_env {

inline std::int64_t EnvInt(const char* name, std::int64_t fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? std::strtoll(v, nullptr, 10) : fallback;
}

inline double EnvDouble(const char* name, double fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? std::strtod(v, nullptr) : fallback;
}

}  // namespace rvehub::testing_env

#endif  // RVEHUB_TESTS_SUPPORT_ENV_UTIL_H_
