// libFuzzer target: the gridscene reader (fuzz_entry.h). Built by the fuzz preset; docs/ROBUSTNESS.md.
#include "tests/fuzz/fuzz_entry.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return gridrt::fuzz::fuzz_one(gridrt::fuzz::Kind::gridscene, data, size);
}
