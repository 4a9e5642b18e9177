// test_vulkan_context.cpp: the Vulkan machinery, independent of the grid: the context and its
// errors, the validation layer (shown to be listening, so that "zero messages" means something),
// buffers and 3D images, R32UI image atomics as the grid's insertion modes use them, the raster
// pipeline of the paper's build (vertex + geometry shader, rasterizer discard), timestamps and the
// float-controls patch.
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <set>
#include <vector>

#include <unistd.h>

#include "gridrt/common/shared/transform.h"
#include "tests/vulkan_test_util.h"
#include "gridrt/vulkan/pipeline.h"

using namespace gridrt;
using namespace gridrt::test;
using namespace gridrt::vulkan;

namespace {
constexpr uint32_t kBlank = 0xFFFFFFFFu;

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

bool any_message_contains(const Context& ctx, const std::string& part) {
  const auto m = ctx.messages();
  return std::any_of(m.begin(), m.end(), [&](const std::string& s) { return contains(s, part); });
}
}  // namespace

TEST_CASE("Vulkan context: a device with what gridrt needs, reported", "[vulkan][unit]") {
  Context& ctx = vk_context();
  ctx.clear_messages();
  const DeviceInfo& info = ctx.info();
  WARN("Vulkan device: " << info.summary());
  CHECK(ctx.validation());
  CHECK(info.api_version >= VK_API_VERSION_1_2);
  CHECK(info.limits.maxImageDimension3D >= 256);  // the Vulkan minimum
  CHECK(info.device_local_heap > 0);
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan validation: a deliberate misuse is reported, so zero messages is not vacuous",
          "[vulkan][unit]") {
  ContextOptions o = ContextOptions::from_env();
  o.validation = true;
  Context scratch(o);
  REQUIRE(scratch.message_count() == 0);

  SECTION("invalid usage: a buffer with no usage bits") {
    VkBufferCreateInfo ci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    ci.size = 64;
    ci.usage = 0;  // VUID-VkBufferCreateInfo-usage-requiredbitmask
    VkBuffer b = VK_NULL_HANDLE;
    if (vkCreateBuffer(scratch.device(), &ci, nullptr, &b) == VK_SUCCESS) vkDestroyBuffer(scratch.device(), b, nullptr);
    CHECK(scratch.message_count() > 0);
    CHECK(any_message_contains(scratch, "usage"));
  }
  SECTION("synchronization: two writes to one buffer without a barrier") {
    Buffer buf = scratch.create_buffer(256, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    scratch.submit([&](VkCommandBuffer cb) {
      vkCmdFillBuffer(cb, buf.buffer, 0, 256, 1u);
      vkCmdFillBuffer(cb, buf.buffer, 0, 256, 2u);  // SYNC-HAZARD-WRITE-AFTER-WRITE
    });
    CHECK(any_message_contains(scratch, "SYNC-HAZARD"));
  }
}

TEST_CASE("Vulkan context: failures are Errors that name the way out", "[vulkan][unit][badinput]") {
  SECTION("no loader") {
    // The loader is opened once per process; a bad path only matters before that. Either way
    // nothing crashes: before, an Error; after, the loaded one is used.
    ContextOptions o;
    o.loader_path = "/nonexistent/libvulkan.so.1";
    try {
      Context c(o);
      SUCCEED("the loader was already open");
    } catch (const Error& e) {
      CHECK(contains(e.what(), "no Vulkan device"));
      CHECK(contains(e.what(), "--backend cpu"));
    }
  }
  SECTION("a device index out of range") {
    ContextOptions o;
    o.device_index = 99;
    try {
      Context c(o);
      FAIL("device 99 accepted");
    } catch (const Error& e) {
      CHECK(contains(e.what(), "no Vulkan device"));
      CHECK(contains(e.what(), "GRIDRT_VK_DEVICE"));
    }
  }
  SECTION("an image over maxImageDimension3D") {
    Context& ctx = vk_context();
    const uint32_t max3d = ctx.info().limits.maxImageDimension3D;
    try {
      ctx.require_image3d({max3d + 1, 4, 4});
      FAIL("image accepted");
    } catch (const Error& e) {
      CHECK(contains(e.what(), "maxImageDimension3D"));
      CHECK(contains(e.what(), "--backend cpu"));
    }
  }
  SECTION("an allocation over the heap") {
    Context& ctx = vk_context();
    CHECK_THROWS_AS(ctx.require_allocation(ctx.info().device_local_heap + 1, "a test"), Error);
  }
}

TEST_CASE("Vulkan 3D image: clear, upload and download round-trip", "[vulkan][unit]") {
  Context& ctx = vk_context();
  ctx.clear_messages();
  Image3D img = ctx.create_image3d({7, 5, 3});
  ctx.clear(img, kBlank);
  std::vector<uint32_t> t = ctx.download(img);
  CHECK(std::all_of(t.begin(), t.end(), [](uint32_t v) { return v == kBlank; }));
  std::iota(t.begin(), t.end(), 100u);
  ctx.upload(img, std::span<const uint32_t>(t));
  CHECK(ctx.download(img) == t);

  Buffer b = ctx.create_buffer(1000, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  std::vector<uint8_t> bytes(1000);
  std::iota(bytes.begin(), bytes.end(), uint8_t(3));
  ctx.upload(b, bytes.data(), bytes.size());
  std::vector<uint8_t> back(1000);
  ctx.download(b, back.data(), back.size());
  CHECK(back == bytes);
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

namespace {
struct AtomicsPush {
  uint32_t mode, capacity, count, cells;
};

// Runs test_image_atomics.comp on a fresh blank image of `cells` cells of `capacity` slots.
std::vector<uint32_t> run_atomics(Context& ctx, uint32_t mode, uint32_t capacity, uint32_t cells,
                                  const std::vector<uint32_t>& values, std::vector<uint32_t>* results = nullptr) {
  // Slots blank, status texels 0.
  Image3D img = ctx.create_image3d({capacity + 1, cells, 1});
  std::vector<uint32_t> init(img.texel_count(), kBlank);
  for (uint32_t y = 0; y < cells; ++y) init[size_t(y) * (capacity + 1) + capacity] = 0u;
  ctx.upload(img, std::span<const uint32_t>(init));
  Buffer vals = ctx.create_buffer(std::max<size_t>(values.size(), 1) * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  ctx.upload(vals, std::span<const uint32_t>(values));
  Buffer res = ctx.create_buffer(16 * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  Descriptors set(ctx, {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                        VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}, VK_SHADER_STAGE_COMPUTE_BIT);
  set.bind(0, img);
  set.bind(1, vals);
  set.bind(2, res);
  Pipeline pipe(ctx, "test_image_atomics.comp", set.layout(), sizeof(AtomicsPush));
  const AtomicsPush push{mode, capacity, uint32_t(values.size()), cells};
  ctx.submit([&](VkCommandBuffer cb) {
    barrier(cb);
    pipe.bind(cb, set.set());
    pipe.push(cb, push);
    vkCmdDispatch(cb, groups(values.size(), 64), 1, 1);
  });
  if (results) *results = ctx.download<uint32_t>(res, 9);
  return ctx.download(img);
}

// Unique pseudo-random references (instance << 16 | triangle), never blank.
std::vector<uint32_t> unique_refs(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::set<uint32_t> s;
  while (s.size() < n) s.insert(rng() % 0xFFFF0000u);
  std::vector<uint32_t> v(s.begin(), s.end());
  std::shuffle(v.begin(), v.end(), rng);
  return v;
}
}  // namespace

TEST_CASE("Vulkan image atomics: the operations the grid uses, on R32UI 3D images", "[vulkan][unit][atomics]") {
  Context& ctx = vk_context();
  ctx.clear_messages();

  SECTION("a known sequence: exchange, compare-and-swap, min (unsigned), or") {
    std::vector<uint32_t> r;
    const std::vector<uint32_t> img = run_atomics(ctx, 0, 1, 1, {0u}, &r);
    const std::vector<uint32_t> expected = {kBlank, 5u, 5u, 7u, 3u, 3u, 0x80000003u, 0x7FFFFFFFu, kBlank};
    CHECK(r == expected);
    CHECK(img[0] == kBlank);
  }

  // Many invocations insert into few cells at once: contention on every slot.
  const uint32_t capacity = 6, cells = 16;
  SECTION("sorted (atomic-min cascade): each cell holds its `capacity` smallest, ascending, whatever the timing") {
    for (uint32_t per_cell : {3u, 6u, 40u}) {
      const std::vector<uint32_t> values = unique_refs(size_t(per_cell) * cells, per_cell);
      const std::vector<uint32_t> img = run_atomics(ctx, 1, capacity, cells, values);
      for (uint32_t y = 0; y < cells; ++y) {
        std::vector<uint32_t> want;
        for (size_t i = y; i < values.size(); i += cells) want.push_back(values[i]);
        std::sort(want.begin(), want.end());
        const bool saturated = want.size() > capacity;
        want.resize(capacity, kBlank);
        const std::vector<uint32_t> got(img.begin() + size_t(y) * (capacity + 1),
                                        img.begin() + size_t(y) * (capacity + 1) + capacity);
        INFO("per cell " << per_cell << ", cell " << y);
        CHECK(got == want);
        CHECK(img[size_t(y) * (capacity + 1) + capacity] == (saturated ? 1u : 0u));
      }
    }
  }
  SECTION("first-empty (compare-and-swap): unsaturated cells hold their references; saturated ones a choice") {
    for (uint32_t per_cell : {3u, 6u, 40u}) {
      const std::vector<uint32_t> values = unique_refs(size_t(per_cell) * cells, 1000 + per_cell);
      const std::vector<uint32_t> img = run_atomics(ctx, 2, capacity, cells, values);
      for (uint32_t y = 0; y < cells; ++y) {
        std::multiset<uint32_t> candidates;
        for (size_t i = y; i < values.size(); i += cells) candidates.insert(values[i]);
        std::multiset<uint32_t> got;
        for (uint32_t s = 0; s < capacity; ++s)
          if (img[size_t(y) * (capacity + 1) + s] != kBlank) got.insert(img[size_t(y) * (capacity + 1) + s]);
        const uint32_t status = img[size_t(y) * (capacity + 1) + capacity];
        INFO("per cell " << per_cell << ", cell " << y);
        if (candidates.size() <= capacity) {
          CHECK(got == candidates);
          CHECK(status == 0u);
        } else {
          CHECK(got.size() == capacity);
          CHECK(std::includes(candidates.begin(), candidates.end(), got.begin(), got.end()));
          CHECK(status == 1u);
        }
      }
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan raster pass: vertex + geometry shader with rasterizer discard, flat instance and triangle ids",
          "[vulkan][unit][raster]") {
  Context& ctx = vk_context();
  ctx.clear_messages();
  constexpr uint32_t kInstances = 3, kTriangles = 50;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-100.0f, 100.0f);
  std::vector<glm::vec4> positions(kTriangles * 3);
  for (glm::vec4& p : positions) p = glm::vec4(u(rng), u(rng), u(rng), 1.0f);
  std::vector<shared::Affine> transforms(kInstances);
  for (shared::Affine& m : transforms)
    m = {glm::vec4(u(rng), u(rng), u(rng), u(rng)), glm::vec4(u(rng), u(rng), u(rng), u(rng)),
         glm::vec4(u(rng), u(rng), u(rng), u(rng))};

  Buffer pos = ctx.create_buffer(positions.size() * 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  Buffer xf = ctx.create_buffer(transforms.size() * sizeof(shared::Affine), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  Buffer out = ctx.create_buffer(kInstances * kTriangles * 48, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  ctx.upload(pos, std::span<const glm::vec4>(positions));
  ctx.upload(xf, std::span<const shared::Affine>(transforms));
  Descriptors set(ctx, {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                        VK_DESCRIPTOR_TYPE_STORAGE_BUFFER});
  set.bind(0, pos);
  set.bind(1, xf);
  set.bind(2, out);
  Pipeline pipe(ctx, "test_raster.vert", "test_raster.geom", set.layout(), sizeof(uint32_t));
  ctx.submit([&](VkCommandBuffer cb) {
    vkCmdFillBuffer(cb, out.buffer, 0, VK_WHOLE_SIZE, 0u);
    barrier(cb);
    pipe.begin_pass(cb);
    pipe.bind(cb, set.set());
    pipe.push(cb, kTriangles);
    for (uint32_t i = 0; i < kInstances; ++i) vkCmdDraw(cb, kTriangles * 3, 1, 0, i);  // firstInstance = id
    pipe.end_pass(cb);
  });
  const std::vector<glm::vec4> got = ctx.download<glm::vec4>(out, kInstances * kTriangles * 3);
  size_t bad = 0;
  for (uint32_t i = 0; i < kInstances; ++i)
    for (uint32_t t = 0; t < kTriangles; ++t) {
      const glm::vec4* g = &got[(i * kTriangles + t) * 3];
      INFO("instance " << i << " triangle " << t);
      CHECK(bits(g[0].w) == i);
      CHECK(bits(g[1].w) == t);
      CHECK(bits(g[2].w) == (i << 16 | t));
      for (int k = 0; k < 3; ++k) {
        const glm::vec3 want = shared::transform_point(transforms[i], glm::vec3(positions[t * 3 + k]));
        for (int a = 0; a < 3; ++a)
          if (bits(g[k][a]) != bits(want[a]) && ++bad <= 5)
            UNSCOPED_INFO("vertex " << k << " axis " << a << ": gpu " << hex(g[k][a]) << " cpu " << hex(want[a]));
      }
    }
  CHECK(bad == 0);
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan timestamps: a dispatch takes a non-negative time", "[vulkan][unit]") {
  Context& ctx = vk_context();
  ctx.clear_messages();
  Timestamps ts(ctx, 2);
  Buffer b = ctx.create_buffer(1 << 20, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  ctx.submit([&](VkCommandBuffer cb) {
    ts.reset(cb);
    ts.write(cb, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    vkCmdFillBuffer(cb, b.buffer, 0, VK_WHOLE_SIZE, 7u);
    ts.write(cb, 1, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  });
  const double ms = ts.elapsed_ms(0, 1);
  CHECK(ms >= 0.0);
  CHECK(ms < 10000.0);
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("SPIR-V float controls: the patched module declares the modes and still validates", "[vulkan][unit]") {
  const auto words = shader_spirv("test_shared_math.comp");
  const std::vector<uint32_t> patched = patch_float_controls(words, {true, true});
  const SpirvFacts f = inspect_spirv(patched);
  CHECK(std::count(f.execution_modes.begin(), f.execution_modes.end(), 4459u) == 1);  // DenormPreserve
  CHECK(std::count(f.execution_modes.begin(), f.execution_modes.end(), 4461u) == 1);  // SignedZeroInfNanPreserve
  CHECK(patch_float_controls(words, {false, false}) == std::vector<uint32_t>(words.begin(), words.end()));
  // spirv-val, where installed (spirv-tools), checks the module's logical layout.
  if (std::system("command -v spirv-val >/dev/null 2>&1") == 0) {
    const auto path = std::filesystem::temp_directory_path() / ("gridrt_patched_" + std::to_string(::getpid()) + ".spv");
    std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(patched.data()), patched.size() * 4);
    const std::string cmd = "spirv-val --target-env vulkan1.2 " + path.string();
    CHECK(std::system(cmd.c_str()) == 0);
    std::filesystem::remove(path);
  }
}

// Run in a child process by the test below, with the loader pointed at no driver at all.
TEST_CASE("Vulkan context without any driver (child process)", "[.nodevice]") {
  try {
    Context c(ContextOptions{});
    FAIL("a context was created without a driver");
  } catch (const Error& e) {
    INFO(e.what());
    CHECK(contains(e.what(), "no Vulkan device"));
    CHECK(contains(e.what(), "--backend cpu"));
  }
}

TEST_CASE("Vulkan context: no driver installed is an Error, not a crash", "[vulkan][unit][badinput]") {
  // VK_DRIVER_FILES (and the older VK_ICD_FILENAMES) replace the loader's driver search.
  const std::string self = std::filesystem::read_symlink("/proc/self/exe").string();
  const std::string cmd = "VK_DRIVER_FILES=/nonexistent/icd.json VK_ICD_FILENAMES=/nonexistent/icd.json '" + self +
                          "' '[.nodevice]' >/dev/null 2>&1";
  CHECK(std::system(cmd.c_str()) == 0);
}
