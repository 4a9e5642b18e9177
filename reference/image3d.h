// image3d.h: the emulated Vulkan 3D image of single-channel uint32 texels, accessed only through
// functions named and shaped like the GLSL image built-ins (imageLoad, imageAtomicCompSwap,
// imageAtomicMin, imageAtomicExchange, imageAtomicOr, imageAtomicAnd, imageStore), so that the
// reference reads like the shader; and an emulated storage buffer of uint32 words with the
// buffer atomics (atomicAdd, atomicOr, atomicAnd). Atomics are relaxed, as GPU atomics are;
// passes are separated by thread joins (the emulated pipeline barriers).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

namespace gridrt::reference {

struct Image3D {
  glm::uvec3 extent{0};
  std::unique_ptr<std::atomic<uint32_t>[]> texels;

  Image3D() = default;
  Image3D(glm::uvec3 e, uint32_t fill) : extent(e), texels(new std::atomic<uint32_t>[size()]) {
    for (size_t i = 0; i < size(); ++i) texels[i].store(fill, std::memory_order_relaxed);
  }
  size_t size() const { return size_t(extent.x) * extent.y * extent.z; }
  size_t index(glm::ivec3 p) const {
    return (size_t(uint32_t(p.z)) * extent.y + uint32_t(p.y)) * extent.x + uint32_t(p.x);
  }
  std::atomic<uint32_t>& at(glm::ivec3 p) const { return texels[index(p)]; }
  // The texels, x fastest (AccelDump layout).
  std::vector<uint32_t> snapshot() const {
    std::vector<uint32_t> out(size());
    for (size_t i = 0; i < out.size(); ++i) out[i] = texels[i].load(std::memory_order_relaxed);
    return out;
  }
};

inline uint32_t imageLoad(const Image3D& image, glm::ivec3 p) {
  return image.at(p).load(std::memory_order_relaxed);
}
inline void imageStore(Image3D& image, glm::ivec3 p, uint32_t data) {
  image.at(p).store(data, std::memory_order_relaxed);
}
// Returns the original value; stores `data` iff the original equals `compare`.
inline uint32_t imageAtomicCompSwap(Image3D& image, glm::ivec3 p, uint32_t compare, uint32_t data) {
  image.at(p).compare_exchange_strong(compare, data, std::memory_order_relaxed);
  return compare;  // compare_exchange writes the original value back into `compare`
}
inline uint32_t imageAtomicMin(Image3D& image, glm::ivec3 p, uint32_t data) {
  std::atomic<uint32_t>& a = image.at(p);
  uint32_t old = a.load(std::memory_order_relaxed);
  while (data < old && !a.compare_exchange_weak(old, data, std::memory_order_relaxed)) {
  }
  return old;
}
inline uint32_t imageAtomicExchange(Image3D& image, glm::ivec3 p, uint32_t data) {
  return image.at(p).exchange(data, std::memory_order_relaxed);
}
inline uint32_t imageAtomicOr(Image3D& image, glm::ivec3 p, uint32_t data) {
  return image.at(p).fetch_or(data, std::memory_order_relaxed);
}
inline uint32_t imageAtomicAnd(Image3D& image, glm::ivec3 p, uint32_t data) {
  return image.at(p).fetch_and(data, std::memory_order_relaxed);
}

// A storage buffer of uint32 words (the grid's dirty-cell list, common/shared/worklist.h).
struct WordBuffer {
  size_t size = 0;
  std::unique_ptr<std::atomic<uint32_t>[]> words;

  WordBuffer() = default;
  WordBuffer(size_t n, uint32_t fill) : size(n), words(new std::atomic<uint32_t>[n]) {
    for (size_t i = 0; i < n; ++i) words[i].store(fill, std::memory_order_relaxed);
  }
  uint32_t load(size_t i) const { return words[i].load(std::memory_order_relaxed); }
  void store(size_t i, uint32_t v) { words[i].store(v, std::memory_order_relaxed); }
  std::vector<uint32_t> snapshot() const {
    std::vector<uint32_t> out(size);
    for (size_t i = 0; i < size; ++i) out[i] = load(i);
    return out;
  }
};

inline uint32_t atomicAdd(WordBuffer& b, size_t i, uint32_t data) {
  return b.words[i].fetch_add(data, std::memory_order_relaxed);
}
inline uint32_t atomicOr(WordBuffer& b, size_t i, uint32_t data) {
  return b.words[i].fetch_or(data, std::memory_order_relaxed);
}
inline uint32_t atomicAnd(WordBuffer& b, size_t i, uint32_t data) {
  return b.words[i].fetch_and(data, std::memory_order_relaxed);
}

}  // namespace gridrt::reference
