// snowmodel: physically plausible fallen snow for glTF scenes.
#include <cstdio>
#include <cstring>
#include <exception>
#include <new>

#include "app/commands.h"
#include "core/error.h"
#include "core/heap.h"
#include "core/log.h"

namespace snow::app {

std::unique_ptr<gl::Context> make_headless_context(const GlobalOptions& global) {
  gl::ContextOptions options;
  options.backend = gl::parse_backend(global.gl_backend);
  return gl::create_context(options);
}

}  // namespace snow::app

int main(int argc, char** argv) {
  using namespace snow;
  tune_heap(argv);
  CLI::App cli{"snowmodel: puts physically plausible fallen snow on glTF 2.0 scenes"};
  cli.set_version_flag("--version", "snowmodel 0.1.0");
  cli.require_subcommand(1);

  app::GlobalOptions global;
  // --help-all is --help with the developer options (hidden from --help)
  // listed: it is known before the options are registered.
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--help-all") == 0) {
      global.help_all = true;
      argv[i] = const_cast<char*>("--help");
    }
  }
  cli.add_flag("-q,--quiet", global.quiet, "Print errors only")->configurable(false);
  cli.add_flag("-v,--verbose", global.verbose, "Print debug messages");
  cli.add_option("--gl-backend", global.gl_backend,
                 "OpenGL backend: auto, egl-device, egl-surfaceless, osmesa, glfw "
                 "(env SNOWMODEL_GL_BACKEND)")
      ->capture_default_str();
  cli.parse_complete_callback([&] {
    set_log_level(global.quiet     ? LogLevel::Quiet
                  : global.verbose ? LogLevel::Debug
                                   : LogLevel::Info);
  });

  app::register_info(cli, global);
  app::register_render(cli, global);
  app::register_snow(cli, global);
  app::register_preview(cli, global);
  app::register_merge(cli, global);

  try {
    cli.parse(argc, argv);
    return kExitOk;
  } catch (const CLI::ParseError& e) {
    const int code = cli.exit(e);
    return code == 0 ? kExitOk : kExitBadInput;
  } catch (const GLError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    if (!e.log().empty()) std::fprintf(stderr, "%s\n", e.log().c_str());
    return e.exit_code();
  } catch (const Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return e.exit_code();
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "error: out of memory\n");
    return kExitInternal;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: internal error: %s\n", e.what());
    return kExitInternal;
  }
}
