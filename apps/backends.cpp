#include "apps/backends.h"

#include "common/scene.h"
#ifdef GRIDRT_HAVE_EMBREE
#  include "common/embree/embree_tracer.h"
#endif

namespace gridrt::app {

std::vector<std::string> backend_names() {
  std::vector<std::string> names;
#ifdef GRIDRT_HAVE_EMBREE
  names.push_back("embree");
#endif
  return names;
}

std::unique_ptr<Tracer> make_backend(const std::string& name) {
#ifdef GRIDRT_HAVE_EMBREE
  if (name == "embree") return std::make_unique<EmbreeTracer>();
#endif
  std::string known;
  for (const std::string& n : backend_names()) known += (known.empty() ? "" : ", ") + n;
  throw Error("unknown backend '" + name + "' (this build has: " + known + ")");
}

}  // namespace gridrt::app
