#pragma once
// One GL context per test process, made on first use (EGL surfaceless or
// OSMesa on llvmpipe, a GPU where there is one) and made current again on
// every call; tests that need GL start with REQUIRE_GL() and skip where no
// context can be made.
#include <cstdio>
#include <memory>

#include "core/error.h"
#include "gl/context.h"

namespace snow::test {

inline gl::Context* context() {
  static std::unique_ptr<gl::Context> ctx = []() -> std::unique_ptr<gl::Context> {
    try {
      return gl::create_context();
    } catch (const Error& e) {
      std::fprintf(stderr, "no GL context: %s\n", e.what());
      return nullptr;
    }
  }();
  if (ctx) ctx->make_current();  // a test may have made another context current
  return ctx.get();
}

}  // namespace snow::test

#define REQUIRE_GL() \
  if (!::snow::test::context()) GTEST_SKIP() << "no OpenGL context"
