#pragma once
// The snowmodel CLI: each subcommand registers itself on the CLI11 app and
// turns its flags into stage settings; the work is done by the stages.
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "gl/context.h"

namespace snow::app {

/// Flags shared by every subcommand.
struct GlobalOptions {
  bool quiet = false;
  bool verbose = false;
  std::string gl_backend = "auto";  // see gl::parse_backend
  bool help_all = false;            // --help-all: --help with the developer options listed
};

/// Creates the headless GL context chosen by --gl-backend (or the
/// SNOWMODEL_GL_BACKEND environment variable); throws GLError (exit 3).
std::unique_ptr<gl::Context> make_headless_context(const GlobalOptions& global);

void register_info(CLI::App& app, const GlobalOptions& global);
void register_render(CLI::App& app, const GlobalOptions& global);
void register_snow(CLI::App& app, const GlobalOptions& global);
void register_preview(CLI::App& app, const GlobalOptions& global);
void register_merge(CLI::App& app, const GlobalOptions& global);

}  // namespace snow::app
