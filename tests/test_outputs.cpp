// The output policy (mesh/output_policy.h) and the atomic writers behind it
// (core/fs.h, mesh/write_maps.h): a careless command never destroys its
// input, a device, a FIFO or another output of the same run; long names
// work; a --maps folder appears whole. End-to-end through the snowmodel
// executable where a command is at stake, on the policy function where a
// run would risk a system file (/dev/null is never written, only named).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <tiny_gltf.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/fs.h"
#include "mesh/gltf_writer.h"
#include "mesh/output_policy.h"
#include "mesh/write_maps.h"
#include "scene/builder.h"
#include "scene/load_gltf.h"
#include "support/command.h"
#include "support/files.h"

namespace snow {
namespace {
namespace fs = std::filesystem;
using test::read_all;
using test::temporaries;
using test::write_all;

const fs::path kCourtyard = fs::path(SNOW_SOURCE_DIR) / "assets/scenes/courtyard.glb";
const std::string kFast = " --max-side 48 --directions 8 --layers 4";

test::CommandResult run(const std::string& args) { return test::run_snowmodel(args); }

std::string q(const fs::path& p) { return test::quoted(p); }

fs::path temp_dir(const std::string& name) { return test::fresh_dir("snow_outputs", name); }

/// A 1 m floor with a table top, as a .gltf (with "<stem>.bin") or .glb.
void save_table(const fs::path& path) {
  SceneBuilder builder;
  builder.add_plane("Floor", 0.0f, {-0.5f, -0.5f}, {0.5f, 0.5f});
  builder.add_box("Top", {-0.2f, 0.3f, -0.2f}, {0.2f, 0.33f, 0.2f});
  tinygltf::Model model;
  append_meshes(model, builder.meshes(), builder.materials(), "Scene");
  save_gltf(model, path);
}

/// Expects the command to be refused (exit 2) with `message` in its one
/// error line.
void expect_refused(const std::string& args, const std::string& message) {
  const test::CommandResult r = run(args);
  EXPECT_EQ(r.code, 2) << args << "\n" << r.output;
  EXPECT_NE(r.output.find("error: " + message), std::string::npos) << args << "\n" << r.output;
  EXPECT_EQ(r.output.find("peel"), std::string::npos) << "refused after the work started\n"
                                                      << r.output;
}

TEST(Outputs, SnowRefusesToWriteOverItsGlbInput) {
  const fs::path dir = temp_dir("glb_input");
  const fs::path input = dir / "scene.glb";
  fs::copy_file(kCourtyard, input);
  fs::create_directories(dir / "sub");
  const std::string bytes = read_all(input);
  expect_refused("snow " + q(input) + kFast + " -o " + q(input),
                 "-o " + input.string() + ": that is the input scene");
  // Spelled another way, through a symlink, or as a hard link.
  expect_refused("snow " + q(input) + kFast + " -o " + q(dir / "sub" / ".." / "scene.glb"),
                 "-o " + (dir / "sub" / ".." / "scene.glb").string() + ": that is the input scene");
  fs::create_symlink(input, dir / "link.glb");
  expect_refused("snow " + q(dir / "link.glb") + kFast + " -o " + q(input), "-o ");
  fs::create_hard_link(input, dir / "hard.glb");
  expect_refused("snow " + q(input) + kFast + " -o " + q(dir / "hard.glb"),
                 "-o " + (dir / "hard.glb").string() + ": that is the input scene");
  expect_refused(
      "snow " + q(input) + kFast + " -o " + q(dir / "out.glb") + " --snow-output " + q(input),
      "--snow-output " + input.string() + ": that is the input scene");
  expect_refused("snow " + q(input) + kFast + " --preview " + q(input),
                 "--preview " + input.string() + ": that is the input scene");
  EXPECT_EQ(read_all(input), bytes);
  EXPECT_FALSE(fs::exists(dir / "out.glb"));
  fs::remove_all(dir);
}

TEST(Outputs, SnowRefusesToWriteOverItsGltfInputOrItsBin) {
  const fs::path dir = temp_dir("gltf_input");
  save_table(dir / "table.gltf");  // and table.bin
  const std::string gltf = read_all(dir / "table.gltf"), bin = read_all(dir / "table.bin");
  expect_refused("snow " + q(dir / "table.gltf") + kFast + " -o " + q(dir / "table.gltf"),
                 "-o " + (dir / "table.gltf").string() + ": that is the input scene");
  // in.gltf keeps its buffer in table.bin: an output table.gltf would write
  // table.bin beside it.
  fs::rename(dir / "table.gltf", dir / "in.gltf");
  expect_refused("snow " + q(dir / "in.gltf") + kFast + " -o " + q(dir / "table.gltf"),
                 "-o " + (dir / "table.gltf").string() + ": it writes " +
                     (dir / "table.bin").string() +
                     " beside it, which is a file of the input scene");
  expect_refused("snow " + q(dir / "in.gltf") + kFast + " -o " + q(dir / "out.glb") +
                     " --snow-output " + q(dir / "table.gltf"),
                 "--snow-output " + (dir / "table.gltf").string() + ": it writes ");
  // A later buffer file of a .gltf output: "<stem>1.bin".
  fs::rename(dir / "table.bin", dir / "table1.bin");
  std::string json = gltf;
  json.replace(json.find("table.bin"), 9, "table1.bin");
  write_all(dir / "in.gltf", json);
  expect_refused("snow " + q(dir / "in.gltf") + kFast + " -o " + q(dir / "table.gltf"),
                 "-o " + (dir / "table.gltf").string() + ": it writes its buffers to table1.bin");
  EXPECT_EQ(read_all(dir / "table1.bin"), bin);
  EXPECT_EQ(read_all(dir / "in.gltf"), json);
  EXPECT_FALSE(fs::exists(dir / "table.gltf"));
  fs::remove_all(dir);
}

TEST(Outputs, RenderAndPreviewRefuseToWriteOverTheInput) {
  const fs::path dir = temp_dir("render_input");
  const fs::path input = dir / "scene.glb";
  fs::copy_file(kCourtyard, input);
  const std::string bytes = read_all(input);
  expect_refused("render " + q(input) + " -o " + q(input),
                 "-o " + input.string() + ": that is the input scene");
  // Refused before the window opens (no display needed).
  expect_refused("preview " + q(input) + " --frames 1 --export " + q(input),
                 "--export " + input.string() + ": that is the input scene");
  expect_refused("preview " + q(input) + " --frames 1 --screenshot " + q(input),
                 "--screenshot " + input.string() + ": that is the input scene");
  EXPECT_EQ(read_all(input), bytes);
  fs::remove_all(dir);
}

TEST(Outputs, AFifoIsNoOutput) {
  const fs::path dir = temp_dir("fifo");
  const fs::path fifo = dir / "pipe.obj";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  expect_refused("snow " + q(kCourtyard) + kFast + " -o " + q(fifo),
                 "-o " + fifo.string() + ": not a regular file (a FIFO)");
  const fs::path png = dir / "pipe.png";
  ASSERT_EQ(mkfifo(png.c_str(), 0600), 0);
  expect_refused("render " + q(kCourtyard) + " -o " + q(png),
                 "-o " + png.string() + ": not a regular file (a FIFO)");
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_TRUE(fs::is_fifo(png));
  // The writers refuse it too, whoever calls them.
  EXPECT_THROW(write_text_atomically(fifo, "x"), IOError);
  EXPECT_TRUE(fs::is_fifo(fifo));
  fs::remove_all(dir);
}

// /dev/null is only named, never written: the policy is asked directly.
TEST(Outputs, DevicesAndFoldersAreNoOutputs) {
  ASSERT_TRUE(fs::is_character_file("/dev/null"));
  try {
    check_output_paths(kCourtyard, {{"-o", "/dev/null", OutputKind::Mesh, MeshFormat::Obj, {}}});
    ADD_FAILURE() << "/dev/null accepted";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "-o /dev/null: not a regular file (a character device)");
  }
  EXPECT_THROW(check_output_paths({}, {{"--screenshot", "/dev/null", OutputKind::File, {}, {}}}),
               InputError);
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
  const fs::path dir = temp_dir("folder");
  try {
    check_output_paths({}, {{"-o", dir, OutputKind::File, {}, {}}});
    ADD_FAILURE() << "a folder accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file (a folder)"), std::string::npos);
  }
  // A maps folder is a folder.
  write_all(dir / "file", "x");
  EXPECT_THROW(check_output_paths({}, {{"--maps", dir / "file", OutputKind::Maps, {}, {}}}),
               InputError);
  fs::remove_all(dir);
}

TEST(Outputs, TwoOutputsOnOnePathAreRefused) {
  const fs::path dir = temp_dir("twice");
  const fs::path out = dir / "out.glb";
  expect_refused("snow " + q(kCourtyard) + kFast + " -o " + q(out) + " --snow-output " +
                     q(dir / "." / "out.glb"),
                 "--snow-output " + (dir / "." / "out.glb").string() + ": the same file as -o");
  expect_refused("snow " + q(kCourtyard) + kFast + " -o " + q(dir / "a.obj") + " --snow-output " +
                     q(dir / "a.obj"),
                 "--snow-output " + (dir / "a.obj").string() + ": the same file as -o");
  // Inside the maps folder, which is replaced whole.
  fs::create_directories(dir / "maps");
  expect_refused("snow " + q(kCourtyard) + kFast + " -o " + q(dir / "maps" / "x.glb") + " --maps " +
                     q(dir / "maps"),
                 "--maps " + (dir / "maps").string() + ": -o " + (dir / "maps" / "x.glb").string() +
                     " lies inside the --maps folder");
  // The policy alone: a PNG named twice; a .gltf's buffer file as another
  // output's companion.
  EXPECT_THROW(check_output_paths({}, {{"--screenshot", dir / "a.png", OutputKind::File, {}, {}},
                                       {"--preview", dir / "a.png", OutputKind::File, {}, {}}}),
               InputError);
  EXPECT_THROW(
      check_output_paths(
          {},
          {{"-o", dir / "a.gltf", OutputKind::Mesh, MeshFormat::Gltf, {}},
           {"--snow-output", dir / "b.ply", OutputKind::Mesh, MeshFormat::Ply, {dir / "a.bin"}}}),
      InputError);
  EXPECT_NO_THROW(check_output_paths(
      kCourtyard, {{"-o", dir / "a.gltf", OutputKind::Mesh, MeshFormat::Gltf, {}},
                   {"--snow-output", dir / "a.obj", OutputKind::Mesh, MeshFormat::Obj, {}},
                   {"--maps", dir / "maps", OutputKind::Maps, {}, {}},
                   {"--preview", dir / "a.png", OutputKind::File, {}, {}}}));
  EXPECT_FALSE(fs::exists(out));
  fs::remove_all(dir);
}

// The settings file beside a 240-byte output name has a 254-byte name: its
// temporary name used to be longer than NAME_MAX (255).
TEST(Outputs, LongOutputNamesWork) {
  const fs::path dir = temp_dir("long");
  const std::string name = std::string(236, 'n') + ".glb";
  const test::CommandResult r = run("snow " + q(kCourtyard) + kFast + " -o " + q(dir / name));
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::is_regular_file(dir / name));
  EXPECT_TRUE(fs::is_regular_file(dir / (name + ".settings.json")));
  // The longest name the system takes, written directly.
  const std::string longest(name_max(dir), 'm');
  write_text_atomically(dir / longest, "x");
  EXPECT_EQ(read_all(dir / longest), "x");
  EXPECT_TRUE(temporaries(dir).empty());
  // Too long for the settings file beside it: said before the work.
  const std::string too_long = std::string(250, 'n') + ".glb";
  expect_refused("snow " + q(kCourtyard) + kFast + " -o " + q(dir / too_long),
                 "-o " + (dir / too_long).string() + ": " +
                     (dir / (too_long + ".settings.json")).string() +
                     " beside it: the name is 268 bytes long");
  fs::remove_all(dir);
}

TEST(Outputs, AFolderIsWrittenAsideAndSwappedIntoPlace) {
  const fs::path dir = temp_dir("folder_swap");
  const fs::path target = dir / "maps";
  fs::path seen_tmp;
  write_folder_atomically(target, [&](const fs::path& tmp) {
    EXPECT_FALSE(fs::exists(target)) << "the folder appears before it is whole";
    EXPECT_TRUE(fs::is_directory(tmp));
    EXPECT_EQ(fs::canonical(tmp.parent_path()), fs::canonical(dir));
    seen_tmp = tmp;
    write_text_atomically(tmp / "a.txt", "new");
  });
  EXPECT_EQ(read_all(target / "a.txt"), "new");
  EXPECT_FALSE(fs::exists(seen_tmp));
  // Replacing: the old folder stays whole while the new one is written and
  // is gone after; a failed write leaves the old one untouched.
  write_text_atomically(target / "old.txt", "old");
  write_folder_atomically(target, [&](const fs::path& tmp) {
    EXPECT_EQ(read_all(target / "old.txt"), "old");
    write_text_atomically(tmp / "b.txt", "b");
  });
  EXPECT_FALSE(fs::exists(target / "old.txt"));
  EXPECT_FALSE(fs::exists(target / "a.txt"));
  EXPECT_EQ(read_all(target / "b.txt"), "b");
  EXPECT_THROW(write_folder_atomically(target,
                                       [&](const fs::path& tmp) {
                                         write_text_atomically(tmp / "c.txt", "c");
                                         throw IOError("disk full");
                                       }),
               IOError);
  EXPECT_EQ(read_all(target / "b.txt"), "b");
  EXPECT_FALSE(fs::exists(target / "c.txt"));
  EXPECT_TRUE(temporaries(dir).empty());
  fs::remove_all(dir);
}

// SIGTERM while the folder is being written removes the temporary folder
// and what it holds.
TEST(Outputs, ASignalRemovesTheTemporaryFolder) {
  const fs::path dir = temp_dir("folder_signal");
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    write_folder_atomically(dir / "maps", [&](const fs::path& tmp) {
      write_text_atomically(tmp / "layer0_height.exr", "x");
      write_text_atomically(tmp / "layer0_height.png", "y");
      raise(SIGTERM);
    });
    _exit(0);  // not reached: the handler re-raises SIGTERM
  }
  int status = 0;
  waitpid(child, &status, 0);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM);
  EXPECT_FALSE(fs::exists(dir / "maps"));
  EXPECT_TRUE(temporaries(dir).empty());
  fs::remove_all(dir);
}

SnowMaps small_maps() {
  SnowMaps maps;
  maps.grid.origin = {0.0f, 0.0f};
  maps.grid.texel = 0.5f;
  maps.grid.width = 4;
  maps.grid.height = 3;
  maps.layers = 1;
  maps.ground.assign(maps.grid.texels(), 1.0f);
  return maps;
}

TEST(Outputs, TheMapsFolderAppearsWholeAndReplacesOnlyMaps) {
  const fs::path dir = temp_dir("maps");
  const SnowMaps maps = small_maps();
  write_maps(dir / "maps", maps);
  ASSERT_TRUE(fs::exists(dir / "maps" / "manifest.json"));
  // A stale layer of an earlier run does not survive the next one.
  write_all(dir / "maps" / "layer7_height.exr", "stale");
  write_maps(dir / "maps", maps);
  EXPECT_TRUE(fs::exists(dir / "maps" / "manifest.json"));
  EXPECT_TRUE(fs::exists(dir / "maps" / "layer0_height.exr"));
  EXPECT_FALSE(fs::exists(dir / "maps" / "layer7_height.exr"));
  EXPECT_TRUE(temporaries(dir).empty());
  // A folder of other files is not replaced.
  fs::create_directories(dir / "photos");
  write_all(dir / "photos" / "a.jpg", "jpeg");
  EXPECT_THROW(write_maps(dir / "photos", maps), InputError);
  EXPECT_EQ(read_all(dir / "photos" / "a.jpg"), "jpeg");
  EXPECT_THROW(check_output_paths({}, {{"--maps", dir / "photos", OutputKind::Maps, {}, {}}}),
               InputError);
  // Nor one that holds the input.
  fs::create_directories(dir / "scenes");
  fs::copy_file(kCourtyard, dir / "scenes" / "in.glb");
  EXPECT_THROW(check_output_paths(dir / "scenes" / "in.glb",
                                  {{"--maps", dir / "scenes", OutputKind::Maps, {}, {}}}),
               InputError);
  // An empty folder is.
  fs::create_directories(dir / "empty");
  write_maps(dir / "empty", maps);
  EXPECT_TRUE(fs::exists(dir / "empty" / "manifest.json"));
  fs::remove_all(dir);
}

TEST(Outputs, GltfInputFilesListsBuffersAndImages) {
  const fs::path dir = temp_dir("input_files");
  write_all(dir / "a.gltf", R"({"asset":{"version":"2.0"},
    "buffers":[{"uri":"a.bin","byteLength":4},{"uri":"data:application/octet-stream;base64,AAAA"},
               {"uri":"sub/b%20c.bin"}],
    "images":[{"uri":"tex.png"},{"bufferView":0}],
    "extras":{"deep":[[[[[[{"uri":"not.bin"}]]]]]]}})");
  const std::vector<fs::path> files = gltf_input_files(dir / "a.gltf");
  ASSERT_EQ(files.size(), 4u);
  EXPECT_EQ(files[0], dir / "a.gltf");
  EXPECT_EQ(files[1], dir / "a.bin");
  EXPECT_EQ(files[2], dir / "sub" / "b c.bin");
  EXPECT_EQ(files[3], dir / "tex.png");
  // Broken JSON, a FIFO, a missing file: the file alone.
  write_all(dir / "broken.gltf", R"({"buffers":[{"uri":"a.bin"})");
  EXPECT_EQ(gltf_input_files(dir / "broken.gltf").size(), 1u);
  ASSERT_EQ(mkfifo((dir / "fifo.gltf").c_str(), 0600), 0);
  EXPECT_EQ(gltf_input_files(dir / "fifo.gltf").size(), 1u);
  EXPECT_EQ(gltf_input_files(dir / "missing.gltf").size(), 1u);
  // A GLB's JSON chunk: its own buffer has no uri, an external one has.
  EXPECT_EQ(gltf_input_files(kCourtyard).size(), 1u);
  std::string json = R"({"asset":{"version":"2.0"},"buffers":[{"uri":"ext.bin"}]})";
  json.resize((json.size() + 3) & ~size_t(3), ' ');
  const auto u32 = [](uint32_t v) {
    return std::string{char(v & 0xFF), char((v >> 8) & 0xFF), char((v >> 16) & 0xFF),
                       char(v >> 24)};
  };
  write_all(dir / "ext.glb", "glTF" + u32(2) + u32(uint32_t(20 + json.size())) +
                                 u32(uint32_t(json.size())) + "JSON" + json);
  const std::vector<fs::path> glb = gltf_input_files(dir / "ext.glb");
  ASSERT_EQ(glb.size(), 2u);
  EXPECT_EQ(glb[1], dir / "ext.bin");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace snow
