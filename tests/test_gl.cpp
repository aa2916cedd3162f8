// Tests of src/gl: context backends, RAII objects, programs and errors.
#include <gtest/gtest.h>

#include <cstdlib>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.h"
#include "gl/context.h"
#include "gl/context_internal.h"
#include "gl/gl.h"
#include "gl/objects.h"
#include "gl/program.h"

// Sanitizer builds: Mesa's OSMesa never frees the buffers that
// OSMesaMakeCurrent creates; that is not ours to fix.
extern "C" const char* __lsan_default_suppressions() { return "leak:libOSMesa.so\n"; }

namespace snow::gl {
namespace {

constexpr int kSize = 64;  // pixels of the test framebuffer

const char* kTriangleVert = R"(#version 430 core
#include "bindings.h"
layout(location = SNOW_ATTR_POSITION) in vec2 position;
void main() { gl_Position = vec4(position, 0.0, 1.0); }
)";
const char* kTriangleFrag = R"(#version 430 core
layout(location = 0) out vec4 color;
uniform vec4 u_color;
void main() { color = u_color; }
)";

struct Rgba {
  int r, g, b, a;
};

// Renders a red triangle (-0.5,-0.5) (0.5,-0.5) (0,0.5) over a blue clear
// colour into a kSize x kSize RGBA8 FBO; returns the pixels, bottom row first.
std::vector<uint8_t> render_triangle() {
  Texture color = create_texture_2d(GL_RGBA8, kSize, kSize, "test colour");
  Framebuffer fbo = create_framebuffer();
  glNamedFramebufferTexture(fbo.id(), GL_COLOR_ATTACHMENT0, color.id(), 0);
  check_framebuffer(fbo, "test fbo");

  const float vertices[] = {-0.5f, -0.5f, 0.5f, -0.5f, 0.0f, 0.5f};
  Buffer vbo = create_buffer();
  glNamedBufferStorage(vbo.id(), sizeof(vertices), vertices, 0);
  VertexArray vao = create_vertex_array();
  glVertexArrayVertexBuffer(vao.id(), 0, vbo.id(), 0, 2 * sizeof(float));
  glEnableVertexArrayAttrib(vao.id(), 0);
  glVertexArrayAttribFormat(vao.id(), 0, 2, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(vao.id(), 0, 0);

  Program program =
      Program::from_sources({{"triangle.vert", kTriangleVert}, {"triangle.frag", kTriangleFrag}});
  program.set("u_color", glm::vec4(1.0f, 0.0f, 0.0f, 1.0f));

  glBindFramebuffer(GL_FRAMEBUFFER, fbo.id());
  glViewport(0, 0, kSize, kSize);
  glClearColor(0.0f, 0.0f, 1.0f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  program.use();
  glBindVertexArray(vao.id());
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);

  std::vector<uint8_t> pixels(kSize * kSize * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, kSize, kSize, GL_RGBA, GL_UNSIGNED_BYTE, pixels.data());
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  check_error("render_triangle");
  return pixels;
}

Rgba pixel(const std::vector<uint8_t>& pixels, int x, int y) {
  const uint8_t* p = &pixels[(static_cast<size_t>(y) * kSize + x) * 4];
  return {p[0], p[1], p[2], p[3]};
}

void expect_triangle(const std::vector<uint8_t>& pixels) {
  // Inside: the centroid and points near each corner.
  for (auto [x, y] : {std::pair{32, 26}, std::pair{20, 18}, std::pair{44, 18}, std::pair{32, 44}}) {
    const Rgba p = pixel(pixels, x, y);
    EXPECT_EQ(p.r, 255) << "at " << x << "," << y;
    EXPECT_EQ(p.g, 0) << "at " << x << "," << y;
    EXPECT_EQ(p.b, 0) << "at " << x << "," << y;
  }
  // Outside: corners, below the base, beside the apex.
  for (auto [x, y] : {std::pair{1, 1}, std::pair{62, 62}, std::pair{32, 10}, std::pair{20, 44},
                      std::pair{44, 44}}) {
    const Rgba p = pixel(pixels, x, y);
    EXPECT_EQ(p.r, 0) << "at " << x << "," << y;
    EXPECT_EQ(p.b, 255) << "at " << x << "," << y;
  }
  // Coverage: the triangle covers 1/8 of the NDC square.
  int red = 0;
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) red += pixel(pixels, x, y).r > 127 ? 1 : 0;
  }
  EXPECT_NEAR(red, kSize * kSize / 8, kSize);
}

std::unique_ptr<Context> make(Backend backend) {
  ContextOptions options;
  options.backend = backend;
  options.visible = false;
  options.window_width = 64;
  options.window_height = 64;
  return create_context(options);
}

bool has_display() {
  const char* x = std::getenv("DISPLAY");
  const char* w = std::getenv("WAYLAND_DISPLAY");
  return (x && *x) || (w && *w);
}

void check_backend_renders(Backend backend) {
  auto context = make(backend);
  ASSERT_TRUE(context);
  EXPECT_EQ(context->backend(), backend);
  const std::string description = context->description();
  EXPECT_NE(description.find(" | "), std::string::npos) << description;
  EXPECT_NE(description.find(" | ", description.find(" | ") + 3), std::string::npos) << description;
  GLint major = 0;
  GLint minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  EXPECT_GE(major * 10 + minor, 43) << description;
  expect_triangle(render_triangle());
}

TEST(GlContext, EglSurfacelessRendersTriangle) { check_backend_renders(Backend::EglSurfaceless); }

TEST(GlContext, OSMesaRendersTriangle) { check_backend_renders(Backend::OSMesa); }

TEST(GlContext, EglDeviceRendersTriangleIfPresent) {
  std::unique_ptr<Context> context;
  try {
    context = make(Backend::EglDevice);
  } catch (const GLError& e) {
    GTEST_SKIP() << "no EGL device here: " << e.what();
  }
  context.reset();
  check_backend_renders(Backend::EglDevice);
}

TEST(GlContext, GlfwRendersTriangleWithDisplay) {
  if (!has_display()) GTEST_SKIP() << "no DISPLAY (the xvfb-run ctest entry covers GLFW)";
  check_backend_renders(Backend::Glfw);
}

TEST(GlContext, AutoGivesAHeadlessContext) {
  ContextOptions options;  // Auto, unless SNOWMODEL_GL_BACKEND says otherwise
  auto context = create_context(options);
  EXPECT_NE(context->backend(), Backend::Auto);
  expect_triangle(render_triangle());
}

TEST(GlContext, EnvironmentOverridesAuto) {
  setenv("SNOWMODEL_GL_BACKEND", "osmesa", 1);
  auto context = create_context({});
  EXPECT_EQ(context->backend(), Backend::OSMesa);
  context.reset();
  setenv("SNOWMODEL_GL_BACKEND", "no-such-backend", 1);
  EXPECT_THROW(create_context({}), InputError);
  unsetenv("SNOWMODEL_GL_BACKEND");
}

// The probe tells what a context would render with, without making one: it
// agrees with the renderer of the context the same options then give.
TEST(GlContext, ProbeForeseesTheRenderer) {
  EXPECT_EQ(probe_software(ContextOptions{Backend::OSMesa}), std::optional<bool>(true));
  EXPECT_EQ(probe_software(ContextOptions{Backend::Glfw}), std::nullopt);
  const std::optional<bool> software = probe_software();
  if (!software) GTEST_SKIP() << "EGL cannot list its devices";
  auto context = create_context();
  EXPECT_EQ(*software, renderer_is_software()) << context->description();
}

// An on-demand context is made by the first pass that needs GL, and not
// before: until then it answers renderer_is_software() with what it was
// told; it is released with the object.
TEST(GlContext, OnDemandContextIsMadeByTheFirstPassThatNeedsIt) {
  int made = 0;
  {
    OnDemandContext on_demand(
        [&made] {
          ++made;
          return create_context();
        },
        true);
    EXPECT_FALSE(on_demand.made());
    EXPECT_TRUE(renderer_is_software());
    EXPECT_THROW(OnDemandContext([] { return create_context(); }, false), std::logic_error);
    require_context();
    require_context();
    EXPECT_TRUE(on_demand.made());
    EXPECT_EQ(made, 1);
    expect_triangle(render_triangle());
  }
  require_context();  // none installed: nothing to make
  EXPECT_EQ(made, 1);
  OnDemandContext other([] { return create_context(); }, false);  // installable again
  EXPECT_FALSE(renderer_is_software());
}

TEST(GlContext, ContextsOfDifferentBackendsLiveTogether) {
  auto egl = make(Backend::EglSurfaceless);
  auto osmesa = make(Backend::OSMesa);  // now current
  expect_triangle(render_triangle());
  egl->make_current();
  expect_triangle(render_triangle());
  osmesa->make_current();
  expect_triangle(render_triangle());
  osmesa.reset();
  egl->make_current();
  expect_triangle(render_triangle());
}

TEST(GlContext, BackendNames) {
  for (Backend b : {Backend::Auto, Backend::EglDevice, Backend::EglSurfaceless, Backend::OSMesa,
                    Backend::Glfw}) {
    EXPECT_EQ(parse_backend(to_string(b)), b);
  }
  EXPECT_EQ(to_string(Backend::EglSurfaceless), "egl-surfaceless");
  try {
    parse_backend("vulkan");
    FAIL() << "no InputError";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("vulkan"), std::string::npos) << message;
    EXPECT_NE(message.find("egl-surfaceless"), std::string::npos) << message;
  }
}

TEST(GlContext, FailureMessageListsEachBackendTried) {
  // Without a display GLFW must fail; the message names it with its reason.
  const char* display = std::getenv("DISPLAY");
  const char* wayland = std::getenv("WAYLAND_DISPLAY");
  const std::string saved = display ? display : "";
  const std::string saved_wayland = wayland ? wayland : "";
  unsetenv("DISPLAY");
  unsetenv("WAYLAND_DISPLAY");
  try {
    make(Backend::Glfw);
    ADD_FAILURE() << "GLFW worked without a display";
  } catch (const GLError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind("no usable OpenGL: glfw: ", 0), 0u) << message;
    EXPECT_GT(message.size(), std::string("no usable OpenGL: glfw: ").size()) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_FALSE(e.log().empty());
  }
  // Two backends: each is named, in order, separated by "; ".
  try {
    auto context = detail::try_backends({Backend::EglDevice, Backend::Glfw}, {});
    EXPECT_EQ(context->backend(), Backend::EglDevice);  // a GPU machine
  } catch (const GLError& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.rfind("no usable OpenGL: egl-device: ", 0), 0u) << message;
    const size_t glfw = message.find("; glfw: ");
    EXPECT_NE(glfw, std::string::npos) << message;
  }
  if (!saved.empty()) setenv("DISPLAY", saved.c_str(), 1);
  if (!saved_wayland.empty()) setenv("WAYLAND_DISPLAY", saved_wayland.c_str(), 1);
}

class GlTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ContextOptions options;
    options.backend = Backend::EglSurfaceless;
    options.debug = true;
    context_ = create_context(options);
  }
  std::unique_ptr<Context> context_;
};

TEST_F(GlTest, CheckErrorNamesWhatAndEnum) {
  EXPECT_NO_THROW(check_error("clean"));
  glEnable(0xDEAD);  // not a capability
  try {
    check_error("probe step");
    FAIL() << "no GLError";
  } catch (const GLError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("probe step"), std::string::npos) << message;
    EXPECT_NE(message.find("GL_INVALID_ENUM"), std::string::npos) << message;
  }
  EXPECT_NO_THROW(check_error("after"));  // the error was consumed
}

TEST_F(GlTest, HandlesMoveAndFree) {
  Buffer a = create_buffer();
  const GLuint id = a.id();
  ASSERT_NE(id, 0u);
  EXPECT_TRUE(glIsBuffer(id));
  Buffer b(std::move(a));
  EXPECT_EQ(a.id(), 0u);  // NOLINT(bugprone-use-after-move)
  EXPECT_FALSE(a);
  EXPECT_EQ(b.id(), id);
  Buffer c = create_buffer();
  const GLuint other = c.id();
  c = std::move(b);  // frees `other`
  EXPECT_EQ(c.id(), id);
  EXPECT_FALSE(glIsBuffer(other));
  { Buffer d(std::move(c)); }
  EXPECT_FALSE(glIsBuffer(id));
  Texture t = create_texture(GL_TEXTURE_2D);
  const GLuint tid = t.id();
  EXPECT_TRUE(glIsTexture(tid));
  t.reset();
  EXPECT_FALSE(glIsTexture(tid));
  EXPECT_FALSE(t);
}

TEST_F(GlTest, TextureAllocationErrorsAreGLErrors) {
  Texture ok = create_texture_2d_array(GL_R32F, 16, 16, 3, "small array");
  GLint layers = 0;
  glGetTextureLevelParameteriv(ok.id(), 0, GL_TEXTURE_DEPTH, &layers);
  EXPECT_EQ(layers, 3);
  try {
    create_texture_2d(GL_RGBA32F, 1 << 20, 1 << 20, "huge map");
    FAIL() << "no GLError";
  } catch (const GLError& e) {
    EXPECT_NE(std::string(e.what()).find("huge map"), std::string::npos) << e.what();
  }
  EXPECT_THROW(create_texture_2d(GL_R8, 0, 4, "empty"), GLError);
}

TEST_F(GlTest, IncompleteFramebufferThrows) {
  Framebuffer fbo = create_framebuffer();
  try {
    check_framebuffer(fbo, "empty fbo");
    FAIL() << "no GLError";
  } catch (const GLError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("empty fbo"), std::string::npos) << message;
    EXPECT_NE(message.find("INCOMPLETE"), std::string::npos) << message;
  }
}

TEST_F(GlTest, CompileErrorNamesFileWithDriverLog) {
  try {
    Program::from_sources({{"broken_test.frag", "#version 430 core\nvoid main() { nope(); }\n"}});
    FAIL() << "no GLError";
  } catch (const GLError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("broken_test.frag"), std::string::npos) << message;
    EXPECT_NE(message.find("compile error"), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_FALSE(e.log().empty());
  }
}

TEST_F(GlTest, LinkErrorNamesFiles) {
  const char* vert = "#version 430 core\nvoid main() { gl_Position = vec4(0.0); }\n";
  // A function declared and called but defined in no stage: a link error on
  // every driver (NVIDIA's links an input no stage writes).
  const char* frag =
      "#version 430 core\nvec3 defined_nowhere();\nout vec4 c;\n"
      "void main() { c = vec4(defined_nowhere(), 1.0); }\n";
  try {
    Program::from_sources({{"a_test.vert", vert}, {"b_test.frag", frag}});
    FAIL() << "no GLError";
  } catch (const GLError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("a_test.vert+b_test.frag"), std::string::npos) << message;
    EXPECT_NE(message.find("link error"), std::string::npos) << message;
  }
}

TEST_F(GlTest, UnknownStageAndFileAreErrors) {
  EXPECT_THROW(Program::from_sources({{"shader.txt", "#version 430\nvoid main() {}\n"}}), GLError);
  EXPECT_THROW(shader_source("no_such_pass.frag"), GLError);
  try {
    Program::from_sources(
        {{"inc_test.frag", "#version 430\n#include \"missing.h\"\nvoid main() {}\n"}});
    FAIL() << "no GLError";
  } catch (const GLError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.h"), std::string::npos) << e.what();
  }
}

TEST_F(GlTest, IncludeIsSplicedAfterVersion) {
  const std::string text =
      resolve_includes("x.frag", "#version 430 core\n#include \"bindings.h\"\nvoid main() {}\n");
  EXPECT_EQ(text.rfind("#version 430 core\n", 0), 0u);
  EXPECT_NE(text.find("SNOW_SHADERS_BINDINGS_H"), std::string::npos);
  EXPECT_EQ(text.find("\n#include"), std::string::npos);
  EXPECT_THROW(resolve_includes("y.frag", "#include \"bindings.h\"\n#version 430\n"), GLError);
}

TEST_F(GlTest, UniformLocationsAreCached) {
  Program program =
      Program::from_sources({{"triangle.vert", kTriangleVert}, {"triangle.frag", kTriangleFrag}});
  const GLint location = program.uniform_location("u_color");
  EXPECT_GE(location, 0);
  EXPECT_EQ(program.uniform_location("u_color"), location);
  EXPECT_EQ(program.uniform_location("not_there"), -1);
  program.set("not_there", 1.0f);  // ignored, no GL error
  EXPECT_NO_THROW(check_error("set unknown uniform"));
  Program moved(std::move(program));
  EXPECT_EQ(moved.uniform_location("u_color"), location);
  EXPECT_EQ(moved.name(), "triangle.vert+triangle.frag");
}

}  // namespace
}  // namespace snow::gl
