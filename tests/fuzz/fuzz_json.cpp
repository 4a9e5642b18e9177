// libFuzzer target: the json reader (fuzz_entry.h). Built by the fuzz preset; docs/ROBUSTNESS.md.
#include "tests/fuzz/fuzz_entry.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return gridrt::fuzz::fuzz_one(gridrt::fuzz::Kind::json, data, size);
}
