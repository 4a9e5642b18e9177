// explain.cpp: an ExplainRecord as text for someone learning the algorithm: every step of the
// traversal, every slot read, every triangle test with the values it decided on (decimal and hex
// bits) and why it was accepted or rejected. The full account of plan/explain_format.h.
#include "gridrt/plan/explain_format.h"
#include "gridrt/plan/records.h"

namespace gridrt::plan {

std::string to_text(const ExplainRecord& rec) { return explain_text(rec, ExplainFormat{}); }

}  // namespace gridrt::plan
