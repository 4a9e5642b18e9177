#version 460
// test_image_atomics.comp: image atomics on an R32UI 3D image as the grid uses them, for
// tests/test_vulkan_context.cpp. Cells are rows of `capacity` slots and one status texel,
// one cell per y.
//   mode 0: invocation 0 runs a fixed sequence on texel (0,0,0) and records every returned value
//   mode 1: sorted insertion, the atomic-min cascade, invocation i inserts values[i] into cell
//           i % cells
//   mode 2: first-empty insertion, compare-and-swap into the first blank slot, status bit 1 when
//           the cell is full
layout(local_size_x = 64) in;
layout(r32ui, binding = 0) uniform coherent uimage3D grid;
layout(std430, binding = 1) readonly buffer Values { uint values[]; };
layout(std430, binding = 2) writeonly buffer Results { uint results[]; };
layout(push_constant) uniform Push { uint mode; uint capacity; uint count; uint cells; } pc;

const uint kBlank = 0xFFFFFFFFu;

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= pc.count) return;
  if (pc.mode == 0u) {
    if (i != 0u) return;
    const ivec3 p = ivec3(0);
    results[0] = imageAtomicExchange(grid, p, 5u);             // blank -> 5
    results[1] = imageAtomicCompSwap(grid, p, kBlank, 7u);     // fails: stays 5
    results[2] = imageAtomicCompSwap(grid, p, 5u, 7u);         // 5 -> 7
    results[3] = imageAtomicMin(grid, p, 3u);                  // 7 -> 3
    results[4] = imageAtomicMin(grid, p, 9u);                  // stays 3
    results[5] = imageAtomicOr(grid, p, 0x80000000u);          // 3 -> 0x80000003
    results[6] = imageAtomicMin(grid, p, 0x7FFFFFFFu);         // unsigned: -> 0x7FFFFFFF
    results[7] = imageAtomicExchange(grid, p, kBlank);         // -> blank
    results[8] = imageLoad(grid, p).x;
    return;
  }
  const int y = int(i % pc.cells);
  uint v = values[i];
  if (pc.mode == 1u) {
    // Sorted: every slot keeps the smaller value, the larger one moves on down the cell.
    for (uint s = 0u; s < pc.capacity && v != kBlank; ++s) {
      const uint old = imageAtomicMin(grid, ivec3(int(s), y, 0), v);
      v = max(old, v);
    }
    if (v != kBlank) imageAtomicOr(grid, ivec3(int(pc.capacity), y, 0), 1u);
  } else {
    // First-empty: the first blank slot that takes the value.
    bool stored = false;
    for (uint s = 0u; s < pc.capacity && !stored; ++s)
      stored = imageAtomicCompSwap(grid, ivec3(int(s), y, 0), kBlank, v) == kBlank;
    if (!stored) imageAtomicOr(grid, ivec3(int(pc.capacity), y, 0), 1u);
  }
}
