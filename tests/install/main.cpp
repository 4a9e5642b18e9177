#include "common/builtin/builtin.h"
#include "reference/grid.h"
#include <cstdio>
int main() {
  gridrt::Scene s = gridrt::make_builtin("cornell");
  gridrt::reference::ReferenceGridTracer t;
  t.build(s, 0.0f);
  std::printf("%s\n", gridrt::reference::to_text(t.stats()).c_str());
}
