// ray_pass.h: what the grid's and the portal's trace passes share: the ray and hit buffers grown
// as needed, and one pass over n rays dispatched in chunks (a dispatch covers at most
// maxComputeWorkGroupCount[0] workgroups of 64), with the explain buffer's header cleared first
// and timestamps around it.
#pragma once

#include <algorithm>
#include <chrono>
#include <span>

#include "gridrt/common/tracer.h"
#include "gridrt/common/util.h"
#include "gridrt/vulkan/context.h"
#include "gridrt/vulkan/pipeline.h"

namespace gridrt::vulkan {

// Makes rays and hits hold `count` rays where they hold fewer; true when they were made anew
// (the caller binds them again).
inline bool grow_ray_buffers(Context& ctx, size_t count, Buffer& rays, Buffer& hits, size_t& capacity) {
  if (count <= capacity) return false;
  rays = ctx.create_buffer(count * sizeof(Ray), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  hits = ctx.create_buffer(count * sizeof(Hit), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  capacity = count;
  return true;
}

// Times of one pass: the host's (submit to fence) and the device's (0 without timestamps).
struct PassTimes {
  double host_ms = 0.0, device_ms = 0.0;
};

// Submits one pass of `pipe` over rays [0, n) in chunks; Push is the shader's push-constant block
// {ray_offset, ray_count, explain_ray, explain_capacity}. `explain` (may be null): its first
// `explain_header` bytes are zeroed first. `stamps` (may be null): queries 0 and 1 around it.
template <class Push>
PassTimes submit_ray_chunks(Context& ctx, const Pipeline& pipe, VkDescriptorSet set, uint32_t n,
                            uint32_t explain_index, uint32_t explain_capacity, const Buffer* explain,
                            VkDeviceSize explain_header, Timestamps* stamps) {
  const uint32_t chunk = ctx.info().limits.maxComputeWorkGroupCount[0] * 64u;
  const auto t0 = std::chrono::steady_clock::now();
  ctx.submit([&](VkCommandBuffer cb) {
    if (explain) {
      vkCmdFillBuffer(cb, explain->buffer, 0, explain_header, 0u);
      barrier(cb);
    }
    if (stamps) stamps->reset(cb), stamps->write(cb, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    pipe.bind(cb, set);
    for (uint32_t first = 0; first < n; first += std::min(chunk, n - first)) {
      const Push push{first, std::min(chunk, n - first), explain_index, explain_capacity};
      pipe.push(cb, push);
      vkCmdDispatch(cb, groups(push.ray_count, 64), 1, 1);
    }
    if (stamps) stamps->write(cb, 1, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  });
  PassTimes t;
  t.host_ms = ms_since(t0);
  t.device_ms = stamps ? stamps->elapsed_ms(0, 1) : 0.0;
  return t;
}

}  // namespace gridrt::vulkan
