// backends.h: the tracers the tool can run, by name.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "common/progress.h"
#include "common/tracer.h"

namespace gridrt::app {

// Names this build knows, in the order `--help` lists them.
std::vector<std::string> backend_names();

// A tracer by name; Error for a name this build does not have (naming the ones it has).
std::unique_ptr<Tracer> make_backend(const std::string& name);

// Wraps a tracer so that every trace() call goes in chunks and advances a progress line.
class ProgressTracer : public Tracer {
 public:
  ProgressTracer(Tracer& inner, Progress& progress) : inner_(inner), progress_(progress) {}
  std::string name() const override { return inner_.name(); }
  void build(const Scene& scene, float time) override { inner_.build(scene, time); }
  void update(float time) override { inner_.update(time); }
  void trace(std::span<const Ray> rays, std::span<Hit> hits) override {
    constexpr size_t kChunk = 1 << 14;
    for (size_t i = 0; i < rays.size(); i += kChunk) {
      const size_t n = std::min(kChunk, rays.size() - i);
      inner_.trace(rays.subspan(i, n), hits.subspan(i, n));
      progress_.advance(n);
    }
  }
  AccelDump dump() const override { return inner_.dump(); }

 private:
  Tracer& inner_;
  Progress& progress_;
};

}  // namespace gridrt::app
