// The planner (src/plan): its choices on made-up machines and scenes,
// plain data in and out, no GL.
#include <gtest/gtest.h>

#include "plan/plan.h"

namespace snow::plan {
namespace {

MachineInfo software_two_cores() {
  MachineInfo m;
  m.software = true;
  m.cores = 2;
  return m;
}

MachineInfo gpu_sixteen_cores() {
  MachineInfo m;
  m.software = false;
  m.cores = 16;
  return m;
}

// A courtyard-like scene: 24.96 m across on 1024 texels, 1k triangles.
SceneStats small_scene() {
  SceneStats s;
  s.input_bytes = 100 << 10;
  s.triangles = 1000;
  s.asked_grid_side = 1024;
  s.asked_grid_texel = 24.96f / 1024.0f;
  s.grid_columns = 1024 * 1024;
  return s;
}

TEST(Plan, SoftwareTwoCoresRunsOnTheCpuAndStartsGlOnlyWhenNeeded) {
  const MachineInfo m = software_two_cores();
  EXPECT_FALSE(warm_up_gl(m, 1ull << 30));  // small scenes in software need no GL at all
  const RunPlan p = plan_run(small_scene(), m, Settings{}, false);
  EXPECT_EQ(p.maps.max_side, kAutoMaxSide);
  EXPECT_TRUE(p.maps.note.empty());
  EXPECT_TRUE(p.gl.software);
  EXPECT_FALSE(p.gl.started);
  EXPECT_FALSE(p.bvh_ahead);  // the CPU peel takes every core
  EXPECT_TRUE(p.stabilizer_on_cpu);
  EXPECT_TRUE(p.preview_stabilizer_on_cpu);
  // The peel goes to the CPU unless the triangles' boxes hold more than
  // kCpuPeelHits texel centres, or 4 per layer texel on big maps.
  EXPECT_EQ(choose_peel("auto", p.gl, 1000).cpu_box_texels, kCpuPeelHits);
  EXPECT_EQ(choose_peel("auto", p.gl, size_t(8) << 20).cpu_box_texels, size_t(32) << 20);
  EXPECT_FALSE(choose_peel("auto", p.gl, 1000).always_cpu);
}

TEST(Plan, SixteenCoreGpuWarmsUpForLargeInputsAndBuildsTheBvhBesideThePeel) {
  const MachineInfo m = gpu_sixteen_cores();
  EXPECT_TRUE(warm_up_gl(m, kWarmUpInputBytes));
  EXPECT_FALSE(warm_up_gl(m, kWarmUpInputBytes - 1));
  const RunPlan cold = plan_run(small_scene(), m, Settings{}, false);
  EXPECT_FALSE(cold.gl.software);
  EXPECT_FALSE(cold.gl.started);
  EXPECT_TRUE(cold.bvh_ahead);
  EXPECT_TRUE(cold.stabilizer_on_cpu);           // the batch job's passes beat the GPU's
  EXPECT_FALSE(cold.preview_stabilizer_on_cpu);  // the preview draws the GPU's depth
  // Before the driver has started, a small scene peels on the CPU; after, on the GPU.
  EXPECT_EQ(choose_peel("auto", cold.gl, 1000).cpu_box_texels, kCpuPeelHitsBeforeGl);
  const RunPlan warm = plan_run(small_scene(), m, Settings{}, true);
  EXPECT_TRUE(warm.gl.started);
  const PeelChoice gpu = choose_peel("auto", warm.gl, 1000);
  EXPECT_FALSE(gpu.always_cpu);
  EXPECT_EQ(gpu.cpu_box_texels, 0u);
}

TEST(Plan, UnknownRendererStartsGlUpFrontAndAWindowNeverWarmsUp) {
  MachineInfo m;  // only a context can tell
  EXPECT_TRUE(warm_up_gl(m, 0));
  EXPECT_TRUE(plan_run(small_scene(), m, Settings{}, false).gl.started);
  EXPECT_FALSE(plan_run(small_scene(), m, Settings{}, false).bvh_ahead);
  m.window_backend = true;
  EXPECT_FALSE(warm_up_gl(m, 1ull << 30));
}

TEST(Plan, DeepSnowGetsACoarserAutomaticSideAndAnExplicitOneIsKept) {
  Settings deep;
  deep.fall_depth = 2.0f;  // 200 texels deep on 1 cm texels
  const int side = plan_maps(deep, 1024, 0.01f).max_side;
  EXPECT_EQ(side, int(1024 * kAimTexels * 0.01f / 2.0f));
  EXPECT_NE(plan_maps(deep, 1024, 0.01f).note.find("automatic side " + std::to_string(side)),
            std::string::npos);
  EXPECT_EQ(plan_maps(deep, 1024, 10.0f).max_side, kAutoMaxSide);  // 0.2 texels deep
  EXPECT_EQ(side_for_depth(100, 0.001f, 5.0f), kMinAutoSide);
  Settings fixed = deep;
  fixed.max_side = 4096;
  EXPECT_EQ(plan_maps(fixed, 4096, 0.0025f).max_side, 4096);
  EXPECT_TRUE(plan_maps(fixed, 4096, 0.0025f).note.empty());
  Settings texel = deep;
  texel.texel = 0.01f;
  EXPECT_EQ(plan_maps(texel, 1024, 0.01f).max_side, 0);  // the texel rules
}

TEST(Plan, HugeSceneTurnsHugePagesOffOnlyWhereTheHostTakesMemoryBack) {
  MachineInfo m = software_two_cores();
  SceneStats huge = small_scene();
  huge.input_bytes = uint64_t(2) << 30;
  huge.triangles = 50'000'000;
  huge.grid_columns = size_t(8192) * 8192;
  EXPECT_FALSE(plan_run(huge, m, Settings{}, false).huge_pages_off);
  m.reports_free_pages = true;
  EXPECT_TRUE(plan_run(huge, m, Settings{}, false).huge_pages_off);
  EXPECT_TRUE(huge_pages_off(m, kLargeJobInputBytes, 0));
  EXPECT_FALSE(huge_pages_off(m, kLargeJobInputBytes - 1, kLargeJobColumns - 1));
  EXPECT_TRUE(huge_pages_off(m, 0, kLargeJobColumns));
  // Far more triangles than texel columns: the coverage BVH is built in Morton order.
  huge.grid_columns = size_t(512) * 512;
  EXPECT_TRUE(plan_run(huge, m, Settings{}, false).bvh_morton);
  EXPECT_FALSE(plan_run(small_scene(), m, Settings{}, false).bvh_morton);
}

TEST(Plan, NamedBackendsAreKept) {
  Settings s;
  s.peel_device = "gpu";
  s.stabilizer = "gpu";
  s.coverage_method = "rays";
  const RunPlan p = plan_run(small_scene(), software_two_cores(), s, false);
  EXPECT_FALSE(p.stabilizer_on_cpu);
  EXPECT_FALSE(p.preview_stabilizer_on_cpu);
  EXPECT_FALSE(choose_peel(s.peel_device, p.gl, 1).always_cpu);
  EXPECT_EQ(choose_peel(s.peel_device, p.gl, 1).cpu_box_texels, 0u);
  EXPECT_TRUE(choose_peel("cpu", p.gl, 1).always_cpu);
  CoverageWork w;
  w.receivers = 10;
  EXPECT_EQ(choose_coverage_method(s.coverage_method, 64, w), CoverageMethod::GpuRays);
  const std::vector<std::string> lines = describe(p);
  ASSERT_FALSE(lines.empty());
  EXPECT_NE(lines[2].find("rays (--coverage-method)"), std::string::npos) << lines[2];
}

bool on_cpu(CoverageMethod m) {
  return m == CoverageMethod::CpuRays || m == CoverageMethod::CpuShadowMaps;
}

// On a GPU whose driver has not started, a CPU method is taken where it
// takes at most kCpuSecondsBeforeGl; more cores make larger jobs qualify.
TEST(Plan, ColdGpuTakesTheCpuForSmallCoverageJobsAndMoreSoWithMoreCores) {
  CoverageWork w;
  w.triangles = 1000;
  w.shadow_texels = 1e4;
  w.software = false;
  w.gl_cold = true;
  w.threads = 2;
  w.receivers = 10;
  EXPECT_TRUE(on_cpu(choose_coverage_method("auto", 64, w)));
  while (on_cpu(choose_coverage_method("auto", 64, w)) && w.receivers < (size_t(1) << 40))
    w.receivers *= 2;  // the first job too slow for 2 cores
  ASSERT_FALSE(on_cpu(choose_coverage_method("auto", 64, w)));
  w.threads = 16;
  EXPECT_TRUE(on_cpu(choose_coverage_method("auto", 64, w)));
  w.gl_cold = false;  // once the driver runs, the GPU's passes cost next to nothing
  EXPECT_FALSE(on_cpu(choose_coverage_method("auto", 64, w)));
}

}  // namespace
}  // namespace snow::plan
