// The output policy (mesh/output_policy.h): which paths a command may write.
#include "mesh/output_policy.h"

#include <algorithm>
#include <cctype>
#include <system_error>

#include "core/error.h"
#include "core/fs.h"
#include "mesh/write_maps.h"
#include "scene/load_gltf.h"

namespace snow {
namespace {
namespace fs = std::filesystem;

/// `path` made absolute, with symlinks in its existing part resolved, ".."
/// folded and no trailing separator.
fs::path resolved(const fs::path& path) {
  std::error_code ec;
  fs::path absolute = fs::absolute(path, ec);
  if (ec) absolute = path;
  fs::path out = fs::weakly_canonical(absolute, ec);
  if (ec) out = absolute.lexically_normal();
  if (!out.has_filename() && out.has_parent_path() && out != out.root_path())
    out = out.parent_path();
  return out;
}

/// True when `a` and `b` are the same file: one inode for files that both
/// exist (hard links too), else the same resolved path.
bool same_file(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) {
    const bool same = fs::equivalent(a, b, ec);
    if (!ec) return same;
  }
  return resolved(a) == resolved(b);
}

/// True when `path` is `folder` or lies below it (both resolved).
bool within(const fs::path& folder, const fs::path& path) {
  const fs::path f = resolved(folder), p = resolved(path);
  auto fi = f.begin(), pi = p.begin();
  for (; fi != f.end(); ++fi, ++pi) {
    if (pi == p.end() || *fi != *pi) return false;
  }
  return true;
}

/// The files written beside a Mesh output that have a fixed name: a .gltf's
/// first buffer file, an OBJ's material library.
std::vector<fs::path> companions(const OutputPath& out) {
  if (out.kind != OutputKind::Mesh) return {};
  if (out.format == MeshFormat::Gltf)
    return {out.path.parent_path() / (out.path.stem().string() + ".bin")};
  if (out.format == MeshFormat::Obj) {
    fs::path mtl = out.path;
    mtl.replace_extension(".mtl");
    return {mtl};
  }
  return {};
}

/// True when the .gltf output `out` may write `file` as one of its buffers:
/// "<stem>.bin", "<stem>1.bin", ... in its folder (mesh/gltf_writer.cpp).
bool gltf_buffer_of(const OutputPath& out, const fs::path& file) {
  if (out.kind != OutputKind::Mesh || out.format != MeshFormat::Gltf) return false;
  const std::string stem = out.path.stem().string();
  const std::string name = file.filename().string();
  if (name.size() < stem.size() + 4 || name.compare(0, stem.size(), stem) != 0 ||
      lower_extension(name) != ".bin" || name.compare(name.size() - 4, 4, ".bin") != 0)
    return false;
  for (size_t k = stem.size(); k + 4 < name.size(); ++k) {
    if (!std::isdigit(static_cast<unsigned char>(name[k]))) return false;
  }
  return same_file(out.path.parent_path().empty() ? fs::path(".") : out.path.parent_path(),
                   file.parent_path().empty() ? fs::path(".") : file.parent_path());
}

/// The files `out` writes that have fixed names: its path (not for Maps),
/// its companions and the files beside it.
std::vector<fs::path> files_of(const OutputPath& out) {
  std::vector<fs::path> files;
  if (out.kind != OutputKind::Maps) files.push_back(out.path);
  for (const fs::path& f : companions(out)) files.push_back(f);
  for (const fs::path& f : out.beside) files.push_back(f);
  return files;
}

/// True when `out` writes `file` (or, for Maps, `file` lies in its folder).
bool writes(const OutputPath& out, const fs::path& file) {
  if (out.kind == OutputKind::Maps) return within(out.path, file);
  if (gltf_buffer_of(out, file)) return true;
  const std::vector<fs::path> files = files_of(out);
  return std::any_of(files.begin(), files.end(),
                     [&](const fs::path& f) { return same_file(f, file); });
}

[[noreturn]] void refuse(const OutputPath& out, const std::string& reason) {
  throw InputError(out.option + " " + out.path.string() + ": " + reason);
}

/// How `file`, written by `out`, is named in a message: "it" for the output
/// itself, "<file> beside it" for the others.
std::string which(const OutputPath& out, const fs::path& file) {
  return file == out.path ? std::string() : file.string() + " beside it: ";
}

void check_one(const OutputPath& out) {
  for (const fs::path& file :
       out.kind == OutputKind::Maps ? std::vector<fs::path>{out.path} : files_of(out)) {
    const fs::path name = resolved(file).filename();
    const fs::path folder = file.parent_path().empty() ? fs::path(".") : file.parent_path();
    const size_t limit = name_max(folder);
    if (name.native().size() > limit) {
      refuse(out, which(out, file) + "the name is " + std::to_string(name.native().size()) +
                      " bytes long, the folder allows " + std::to_string(limit));
    }
  }
  if (out.kind == OutputKind::Maps) {
    std::error_code ec;
    if (fs::exists(out.path, ec) && !fs::is_directory(out.path, ec)) {
      refuse(out, "not a folder");
    }
    if (!replaceable_maps_folder(out.path)) {
      refuse(out,
             "the folder holds files and no snowmodel manifest.json; a maps folder is replaced "
             "whole: name a new or empty folder, or one written by --maps");
    }
    if (within(out.path, fs::current_path(ec))) {
      refuse(out, "it holds the current folder, and a maps folder is replaced whole");
    }
    return;
  }
  for (const fs::path& file : files_of(out)) {
    const std::string why = not_a_regular_file(file);
    if (!why.empty()) refuse(out, which(out, file) + why);
  }
}

void check_against_input(const OutputPath& out, const std::vector<fs::path>& inputs) {
  for (size_t k = 0; k < inputs.size(); ++k) {
    const fs::path& input = inputs[k];
    const std::string what =
        k == 0 ? "the input scene" : "a file of the input scene (" + input.string() + ")";
    if (out.kind == OutputKind::Maps) {
      if (within(out.path, input)) {
        refuse(out, "it holds " + what + ", and a maps folder is replaced whole");
      }
      continue;
    }
    for (const fs::path& file : files_of(out)) {
      if (!same_file(file, input)) continue;
      if (file == out.path) refuse(out, "that is " + what);
      refuse(out, "it writes " + file.string() + " beside it, which is " + what);
    }
    if (gltf_buffer_of(out, input)) {
      refuse(out, "it writes its buffers to " + input.filename().string() +
                      " beside it, which is " + what);
    }
  }
}

void check_pair(const OutputPath& out, const OutputPath& earlier) {
  if (earlier.kind == OutputKind::Maps || out.kind == OutputKind::Maps) {
    const OutputPath& maps = earlier.kind == OutputKind::Maps ? earlier : out;
    const OutputPath& other = earlier.kind == OutputKind::Maps ? out : earlier;
    const std::vector<fs::path> files =
        other.kind == OutputKind::Maps ? std::vector<fs::path>{other.path} : files_of(other);
    for (const fs::path& file : files) {
      if (within(maps.path, file) || (other.kind == OutputKind::Maps && within(file, maps.path))) {
        refuse(out, (&maps == &out ? earlier.option + " " + earlier.path.string() + " lies "
                                   : std::string("it lies ")) +
                        "inside the " + maps.option + " folder, which is replaced whole");
      }
    }
    return;
  }
  for (const fs::path& file : files_of(out)) {
    if (!writes(earlier, file)) continue;
    if (file == out.path && same_file(out.path, earlier.path)) {
      refuse(out, "the same file as " + earlier.option);
    }
    refuse(out, "it writes " + file.string() + ", which " + earlier.option + " writes too");
  }
  for (const fs::path& file : files_of(earlier)) {
    if (writes(out, file)) {
      refuse(out, "it writes " + file.string() + ", which " + earlier.option + " writes too");
    }
  }
}

}  // namespace

void check_output_paths(const fs::path& input, const std::vector<OutputPath>& outputs) {
  const std::vector<fs::path> inputs =
      input.empty() ? std::vector<fs::path>{} : gltf_input_files(input);
  for (size_t k = 0; k < outputs.size(); ++k) {
    check_one(outputs[k]);
    check_against_input(outputs[k], inputs);
    for (size_t j = 0; j < k; ++j) check_pair(outputs[k], outputs[j]);
  }
}

}  // namespace snow
