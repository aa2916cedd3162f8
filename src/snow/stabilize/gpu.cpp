// The stabilizer's GPU backend (the stage's contract: snow/stabilize.h;
// docs/ARCHITECTURE.md, "Stabilizer"): angle of repose relaxation after
// Fearing 2000, section 5, on the snow amount maps of Tokoi 2006; routing of
// what cannot stay as flow routing over a terrain, with a distance-transform
// erosion and pointer jumping. One draw per map layer and pass (the gather
// pass: one draw for all layers, one fragment per column, written through an
// image), ping-pong between two depth texture arrays; the CPU backend is
// CpuStabilizer (snow/stabilize_cpu.h), the same within the backends'
// tolerance (snow/stabilize_cpu.h).
#include "snow/stabilize.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <optional>
#include <string>

#include "core/error.h"
#include "core/parallel.h"
#include "gl/context.h"
#include "gl/gl.h"
#include "gl/objects.h"
#include "gl/program.h"
#include "shaders/bindings.h"
#include "snow/column.h"
#include "snow/deposit.h"

namespace snow {
namespace {

constexpr int kReduceBlock = 16;  // columns per side of a block of the snow sums
constexpr int kTile = 4;          // columns per side of an active tile (all layers)
// Largest moves per check: all, into the void, seen (stabilize_moves.comp).
constexpr int kMoves = 3;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

struct Stabilizer::Impl {
  StabilizeSettings settings;
  MapGrid grid;
  int layers = 0;
  int width = 0, height = 0;
  int reduce_width = 0, reduce_height = 0;
  glm::vec2 distance{0.0f};
  bool route_pending = false;
  bool lost_is_zero = true;      // no pass ran since construction or set_depth
  bool volume_sums = true;       // iterate() sums volume and lost_volume
  bool async_checks = false;     // set_async_checks
  int cur = 0;                   // depth[cur] holds the current snow
  std::vector<uint8_t> surface;  // per layer texel: has a surface
  // The cells with a surface, for pouring the piles on the CPU
  // (settings.deposit_piles; zero pages elsewhere).
  ZeroedArray<glm::vec4> pour_cells;
  std::vector<glm::ivec4> rect;  // per layer: x, y, width, height of its surfaces (0 size: none)

  gl::Texture cells, depth[2], out_a, out_b, code, reduce;
  // Per layer texel: r = holding depth, g = held cap (column.glsl held;
  // set_depth uploads it, the snowfall's add pass raises it).
  gl::Texture holds;
  ZeroedArray<float> hold_data;  // the holding depths (stabilize_holds)
  // The routing's data live in the outflow textures, free between passes
  // (the first pass after the routing computes every tile again): views of
  // the same memory as other formats (see route()).
  gl::Texture code_float, out_a_uint, out_b_uint;
  gl::Texture tile_moves;  // R32UI per tile: largest move of a checked pass (float bits)
  gl::Texture tile_void;   // R32UI per tile: and the largest into the void
  gl::Texture tile_seen;   // R32UI per tile: and the largest the convergence test sees
  std::vector<gl::Framebuffer> fbo_outflow, fbo_depth[2];
  std::vector<gl::Framebuffer> fbo_out_b, fbo_code_float, fbo_code, fbo_out_a_uint, fbo_out_b_uint;
  std::vector<gl::Framebuffer> fbo_stable_both;  // code_float and out_b: the first erosion pass
  gl::Framebuffer fbo_scatter, fbo_reduce, fbo_empty;
  gl::VertexArray vao;
  gl::Query query;
  gl::Program outflow, gather, erode, erode_check, receiver, jump, scatter, apply, add, sums;
  // Active tiles (see "Active tiles" below).
  bool tiled = false;
  int tiles_x = 0, tiles_y = 0;
  gl::Texture tile_relax, tile_erode;  // R32I per tile: stamp of the last pass that changed it
  gl::Texture tile_layers;             // R32UI per tile and layer: 1 where it has a surface
  gl::Texture column;                  // R8UI per column: layers with a surface
  gl::Buffer tile_list;                // per layer a draw-indirect command, then its tiles
  gl::Buffer jump_changed;             // uint: a pointer-jumping pass moved a pointer on
  gl::Program tile_select, outflow_tiled, gather_tiled, erode_tiled, receiver_tiled, jump_tiled;
  double tiles_drawn = 0.0;      // tiles computed by relaxation passes (count_tiles)
  int pass_counter = 0;          // relaxation passes run since construction (their stamps)
  int erode_counter = 0;         // erosion passes run since construction (their stamps)
  std::vector<int> stride_last;  // per stride level: stamp of its last pass since the last
                                 // reset, -1 for none
  StrideSchedule schedule{settings};

  Impl(const SnowMaps& maps, const StabilizeSettings& s);
  void upload_cells(const SnowMaps& maps);
  void create_textures();
  void create_framebuffers();
  void create_programs();
  ~Impl() {
    for (GLsync& f : moves_fence) {
      if (f) glDeleteSync(f);
    }
    release_bindings();
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  // Leaves no program, vertex array or framebuffer of ours bound, so state
  // guards of other passes never restore a name that is about to be deleted.
  static void release_bindings() {
    glUseProgram(0);
    glBindVertexArray(0);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
  }
  size_t count() const { return size_t(layers) * size_t(width) * size_t(height); }
  void set_common(const gl::Program& program) const;
  void per_layer(const gl::Program& program, const std::vector<gl::Framebuffer>& fbos);
  template <class Draw>
  void each_layer(const gl::Program& program, const std::vector<gl::Framebuffer>& fbos, Draw draw);
  void bind(GLuint unit, const gl::Texture& texture) const {
    glBindTextureUnit(unit, texture.id());
  }
  void upload_depth(const std::vector<float>& depth);
  // The holds texture: the holding depths, and the held caps of `depth`
  // as it fell (min(depth, standing height, holding depth); null: none).
  void upload_holds(const std::vector<float>* depth);
  void write_depth(const std::vector<glm::vec2>& data);  // depth and lost snow, every texel
  void write_depth(const std::vector<float>& s, const std::vector<float>& lost);  // the same
  void add_snow(const std::vector<float>& add);
  // depth += scale * amount (an R32F or RGBA32F array, amount in r).
  void add_pass(const gl::Texture& amount, float scale);
  gl::Texture kept_amount;  // set_snow_amount's R32F array (none until then)
  // The routing (snow/stabilize.h, Routing); draining, the excess fills and
  // spills down its paths (spill_excess, on the CPU). Returns the erosion
  // plus jump passes run.
  int route(Routing kind = Routing::Settle);
  // route() of `kind` (not Drain) adding its passes, routed volume (what the
  // scatter summed plus what went into the void since `lost_before`, m^3)
  // and wall time to `result`.
  void route_into(Routing kind, double lost_before, StabilizeResult& result);
  void scatter_routed(int routed);
  void relax_pass(int stride, bool measure);
  void reset_tiles() { stride_last.assign(stride_last.size(), -1); }
  void bind_changed(const gl::Texture& stamps) const {
    glBindImageTexture(SNOW_STABILIZE_TILE_CHANGED, stamps.id(), 0, GL_FALSE, 0, GL_READ_WRITE,
                       GL_R32I);
  }
  void select_tiles(const gl::Texture& stamps, int reach, int since, bool all);
  GLuint selected_tiles();
  template <class Draw>
  void with_tile_lists(Draw draw);
  static void draw_tile_list(int list);
  void tiled_layers(const gl::Program& program, const std::vector<gl::Framebuffer>& fbos);
  void per_column(const gl::Program& program);
  GLuint count_fragments(const gl::Program& program);
  // Per-block sums summed over blocks: depth, lost, out_a.r (the scattered
  // snow after routing); metres.
  glm::dvec3 sum_blocks();
  // The largest move (m) of the last relaxation pass, which must have been
  // measured, the largest into the void and the largest seen.
  glm::vec3 largest_move() const;
  // Asynchronous checks (set_async_checks): the largest moves of a checked
  // pass reduced on the GPU (stabilize_moves.comp) and copied into a slot
  // of a persistently mapped buffer behind a fence, read a check later.
  gl::Buffer moves, moves_read;
  const GLuint* moves_mapped = nullptr;  // 2 slots of kMoves uints
  GLsync moves_fence[2] = {nullptr, nullptr};
  int pending_slot = -1;   // the slot of the check not read yet, -1: none
  int pending_stride = 1;  // its pass's stride
  gl::Program moves_reduce;
  void request_moves(int slot);
  glm::vec3 read_moves(int slot);
  void drop_pending();
  // The largest moves a check decides by, and the stride of their pass:
  // this check's, or with async_checks the one before (none at the first
  // check after a reset).
  std::optional<glm::vec3> checked_moves(int stride, int& measured_stride);
  std::vector<glm::vec2> read_depth() const;
  // pour_pressed_snow on the depth read back; uploads it when snow was poured.
  bool pour_pressed();
  std::vector<float> read_channel(GLenum channel) const;
  StabilizeResult iterate(int passes);
};

Stabilizer::Impl::Impl(const SnowMaps& maps, const StabilizeSettings& s)
    : settings(s), grid(maps.grid), layers(maps.layers) {
  gl::require_context();
  width = grid.width;
  height = grid.height;
  reduce_width = (width + kReduceBlock - 1) / kReduceBlock;
  reduce_height = (height + kReduceBlock - 1) / kReduceBlock;
  distance = glm::vec2(grid.texel, float(double(grid.texel) * std::sqrt(2.0)));

  GLint max_layers = 0;
  glGetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &max_layers);
  if (max_layers > 0 && layers > max_layers) {
    throw GLError("stabilize: " + std::to_string(layers) +
                  " layers exceed GL_MAX_ARRAY_TEXTURE_LAYERS " + std::to_string(max_layers));
  }
  upload_cells(maps);  // its CPU copy of the cells is freed before the pass textures exist
  create_textures();
  create_framebuffers();
  create_programs();
  release_bindings();
  gl::check_error("stabilize: set-up");
}

// The cells (stabilize_cells) and what the passes derive from them: which
// texels have a surface, each layer's rectangle, the tiles and columns with
// a surface, and the cells kept on the CPU for pouring piles.
void Stabilizer::Impl::upload_cells(const SnowMaps& maps) {
  const std::vector<glm::vec4> cell_data = stabilize_cells(maps, settings);
  surface.resize(cell_data.size());
  for (size_t k = 0; k < cell_data.size(); ++k) {
    surface[k] = (int(cell_data[k].w) & kCellSurface) != 0 ? 1 : 0;
  }
  // Passes draw each layer only over the bounding box of its surfaces;
  // texels outside keep their cleared values (no snow, no flow). Active
  // tiles are drawn only in the layers with a surface in them.
  tiles_x = (width + kTile - 1) / kTile;
  tiles_y = (height + kTile - 1) / kTile;
  std::vector<GLuint> occupied(size_t(tiles_x) * size_t(tiles_y) * size_t(layers), 0);
  std::vector<uint8_t> surfaces(size_t(width) * size_t(height), 0);  // per column
  for (int l = 0; l < layers; ++l) {
    glm::ivec2 lo(grid.width, grid.height), hi(-1, -1);
    for (int j = 0; j < grid.height; ++j) {
      for (int i = 0; i < grid.width; ++i) {
        if (!surface[maps.index(l, i, j)]) continue;
        lo = glm::min(lo, glm::ivec2(i, j));
        hi = glm::max(hi, glm::ivec2(i, j));
        occupied[(size_t(l) * tiles_y + size_t(j / kTile)) * tiles_x + size_t(i / kTile)] = 1;
        ++surfaces[size_t(j) * size_t(width) + size_t(i)];
      }
    }
    rect.push_back(hi.x < 0 ? glm::ivec4(0) : glm::ivec4(lo, hi - lo + 1));
  }
  column = gl::create_texture_2d(GL_R8UI, width, height, "stabilize column surfaces");
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTextureSubImage2D(column.id(), 0, 0, 0, width, height, GL_RED_INTEGER, GL_UNSIGNED_BYTE,
                      surfaces.data());
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  tile_layers =
      gl::create_texture_2d_array(GL_R32UI, tiles_x, tiles_y, layers, "stabilize tile layers");
  glTextureSubImage3D(tile_layers.id(), 0, 0, 0, 0, tiles_x, tiles_y, layers, GL_RED_INTEGER,
                      GL_UNSIGNED_INT, occupied.data());
  cells = gl::create_texture_2d_array(GL_RGBA32F, width, height, layers, "stabilize cells");
  glTextureSubImage3D(cells.id(), 0, 0, 0, 0, width, height, layers, GL_RGBA, GL_FLOAT,
                      cell_data.data());
  hold_data = stabilize_holds(maps, settings);
  holds = gl::create_texture_2d_array(GL_RG32F, width, height, layers, "stabilize holds");
  upload_holds(nullptr);
  if (settings.route_steep) {
    // For the piles and the drains' spill, on the CPU; rows on all cores.
    pour_cells = ZeroedArray<glm::vec4>(cell_data.size());
    parallel_for(size_t(layers) * size_t(height), [&](size_t row) {
      for (size_t k = row * size_t(width); k < (row + 1) * size_t(width); ++k) {
        if (surface[k]) pour_cells[k] = cell_data[k];
      }
    });
  }
}

// The pass textures (72 B per layer texel), the tile stamps and lists,
// cleared.
void Stabilizer::Impl::create_textures() {
  for (int x = 0; x < 2; ++x) {
    depth[x] = gl::create_texture_2d_array(GL_RG32F, width, height, layers, "stabilize depth");
  }
  out_a = gl::create_texture_2d_array(GL_RGBA32F, width, height, layers, "stabilize outflow");
  out_b = gl::create_texture_2d_array(GL_RGBA32F, width, height, layers, "stabilize outflow");
  code = gl::create_texture_2d_array(GL_RG32UI, width, height, layers, "stabilize codes");
  code_float = gl::create_texture_view(code, GL_RG32F, layers, "stabilize kept heights");
  out_a_uint = gl::create_texture_view(out_a, GL_RGBA32UI, layers, "stabilize pointers");
  out_b_uint = gl::create_texture_view(out_b, GL_RGBA32UI, layers, "stabilize pointers");
  reduce = gl::create_texture_2d(GL_RGBA32F, reduce_width, reduce_height, "stabilize sums");
  GLfloat point_sizes[2] = {1.0f, 1.0f};
  glGetFloatv(GL_POINT_SIZE_RANGE, point_sizes);
  tiled = settings.active_tiles && point_sizes[1] >= float(kTile);  // tiles are drawn as points
  tile_relax = gl::create_texture_2d(GL_R32I, tiles_x, tiles_y, "stabilize tile stamps");
  tile_erode = gl::create_texture_2d(GL_R32I, tiles_x, tiles_y, "stabilize tile stamps");
  tile_moves = gl::create_texture_2d(GL_R32UI, tiles_x, tiles_y, "stabilize tile moves");
  tile_void = gl::create_texture_2d(GL_R32UI, tiles_x, tiles_y, "stabilize tile void moves");
  tile_seen = gl::create_texture_2d(GL_R32UI, tiles_x, tiles_y, "stabilize tile seen moves");
  const GLint never = -1;
  glClearTexImage(tile_relax.id(), 0, GL_RED_INTEGER, GL_INT, &never);
  glClearTexImage(tile_erode.id(), 0, GL_RED_INTEGER, GL_INT, &never);
  jump_changed = gl::create_buffer();
  glNamedBufferStorage(jump_changed.id(), sizeof(GLuint), nullptr, GL_DYNAMIC_STORAGE_BIT);
  tile_list = gl::create_buffer();
  glNamedBufferStorage(
      tile_list.id(),
      GLsizeiptr(sizeof(GLuint) * size_t(layers + 1) * (4 + size_t(tiles_x) * size_t(tiles_y))),
      nullptr, GL_DYNAMIC_STORAGE_BIT);
  {
    int levels = 1;
    while ((1 << levels) <= settings.max_stride) ++levels;
    stride_last.assign(size_t(levels), -1);
  }
  const float zero[4] = {0, 0, 0, 0};
  const GLuint no_codes[2] = {0xfefefefeu, 0xfefefefeu};  // kCodeNone in every direction
  glClearTexImage(code.id(), 0, GL_RG_INTEGER, GL_UNSIGNED_INT, no_codes);
  glClearTexImage(depth[0].id(), 0, GL_RG, GL_FLOAT, zero);
  glClearTexImage(depth[1].id(), 0, GL_RG, GL_FLOAT, zero);
  glClearTexImage(out_a.id(), 0, GL_RGBA, GL_FLOAT, zero);
  glClearTexImage(out_b.id(), 0, GL_RGBA, GL_FLOAT, zero);
  gl::check_error("stabilize: texture upload");
}

// Per layer, the framebuffers the passes draw into; the layered scatter
// target, the sums' target and the attachment-less one.
void Stabilizer::Impl::create_framebuffers() {
  auto layer_fbo = [&](std::initializer_list<const gl::Texture*> textures, int l) {
    gl::Framebuffer fbo = gl::create_framebuffer();
    GLenum buffers[4];
    int n = 0;
    for (const gl::Texture* t : textures) {
      glNamedFramebufferTextureLayer(fbo.id(), GLenum(GL_COLOR_ATTACHMENT0 + n), t->id(), 0, l);
      buffers[n] = GLenum(GL_COLOR_ATTACHMENT0 + n);
      ++n;
    }
    glNamedFramebufferDrawBuffers(fbo.id(), n, buffers);
    gl::check_framebuffer(fbo, "stabilize framebuffer");
    return fbo;
  };
  for (int l = 0; l < layers; ++l) {
    fbo_outflow.push_back(layer_fbo({&out_a, &out_b, &code}, l));
    for (int x = 0; x < 2; ++x) fbo_depth[x].push_back(layer_fbo({&depth[x]}, l));
    fbo_out_b.push_back(layer_fbo({&out_b}, l));
    fbo_code_float.push_back(layer_fbo({&code_float}, l));
    fbo_stable_both.push_back(layer_fbo({&code_float, &out_b}, l));
    fbo_code.push_back(layer_fbo({&code}, l));
    fbo_out_a_uint.push_back(layer_fbo({&out_a_uint}, l));
    fbo_out_b_uint.push_back(layer_fbo({&out_b_uint}, l));
  }
  fbo_scatter = gl::create_framebuffer();
  glNamedFramebufferTexture(fbo_scatter.id(), GL_COLOR_ATTACHMENT0, out_a.id(), 0);  // layered
  gl::check_framebuffer(fbo_scatter, "stabilize scatter framebuffer");
  fbo_reduce = gl::create_framebuffer();
  glNamedFramebufferTexture(fbo_reduce.id(), GL_COLOR_ATTACHMENT0, reduce.id(), 0);
  gl::check_framebuffer(fbo_reduce, "stabilize sums framebuffer");
  fbo_empty = gl::create_framebuffer();
  glNamedFramebufferParameteri(fbo_empty.id(), GL_FRAMEBUFFER_DEFAULT_WIDTH, width);
  glNamedFramebufferParameteri(fbo_empty.id(), GL_FRAMEBUFFER_DEFAULT_HEIGHT, height);
  glNamedFramebufferDrawBuffer(fbo_empty.id(), GL_NONE);
  gl::check_framebuffer(fbo_empty, "stabilize check framebuffer");
}

// The passes' programs with the uniforms common to all.
void Stabilizer::Impl::create_programs() {
  vao = gl::create_vertex_array();
  query = gl::create_query(GL_SAMPLES_PASSED);
  outflow = gl::Program({"stabilize.vert", "stabilize_outflow.frag"});
  gather = gl::Program({"stabilize.vert", "stabilize_gather.frag"});
  erode = gl::Program({"stabilize.vert", "stabilize_erode.frag"});
  erode_check = gl::Program({"stabilize.vert", "stabilize_erode_check.frag"});
  receiver = gl::Program({"stabilize.vert", "stabilize_receiver.frag"});
  jump = gl::Program({"stabilize.vert", "stabilize_jump.frag"});
  scatter =
      gl::Program({"stabilize_scatter.vert", "stabilize_scatter.geom", "stabilize_scatter.frag"});
  apply = gl::Program({"stabilize.vert", "stabilize_apply.frag"});
  add = gl::Program({"stabilize.vert", "stabilize_add.frag"});
  sums = gl::Program({"stabilize.vert", "stabilize_sums.frag"});
  tile_select = gl::Program({"stabilize_tiles.comp"});
  moves_reduce = gl::Program({"stabilize_moves.comp"});
  moves_reduce.set("u_tiles", glm::ivec2(tiles_x, tiles_y));
  outflow_tiled = gl::Program({"stabilize_tile.vert", "stabilize_outflow.frag"});
  gather_tiled = gl::Program({"stabilize_tile.vert", "stabilize_gather.frag"});
  erode_tiled = gl::Program({"stabilize_tile.vert", "stabilize_erode.frag"});
  receiver_tiled = gl::Program({"stabilize_tile.vert", "stabilize_receiver.frag"});
  jump_tiled = gl::Program({"stabilize_tile.vert", "stabilize_jump.frag"});
  for (const gl::Program* p :
       {&outflow, &gather, &erode, &erode_check, &receiver, &jump, &scatter, &apply, &add, &sums,
        &outflow_tiled, &gather_tiled, &erode_tiled, &receiver_tiled, &jump_tiled}) {
    set_common(*p);
    p->set("u_stride", 1);
    p->set("u_tile", kTile);
  }
  tile_select.set("u_tiles", glm::ivec2(tiles_x, tiles_y));
  tile_select.set("u_layers", layers);
  for (const gl::Program* p :
       {&outflow_tiled, &gather_tiled, &erode_tiled, &receiver_tiled, &jump_tiled}) {
    p->set("u_viewport", glm::ivec2(tiles_x * kTile, tiles_y * kTile));
  }
  sums.set("u_block", kReduceBlock);
}

void Stabilizer::Impl::set_common(const gl::Program& program) const {
  program.set("u_size", glm::ivec2(width, height));
  program.set("u_layers", layers);
  program.set("u_distance", distance);
  program.set("u_rise", kSurfaceContinuityTexels * grid.texel);
  program.set("u_min_move", min_move_of(settings));
  program.set("u_stand", settings.cohesion.stand_height);
}

// draw(l) once per layer l with surfaces, into fbos[l] with u_layer = l and
// the scissor on the layer's rectangle; `program` is in use.
template <class Draw>
void Stabilizer::Impl::each_layer(const gl::Program& program,
                                  const std::vector<gl::Framebuffer>& fbos, Draw draw) {
  glEnable(GL_SCISSOR_TEST);
  for (int l = 0; l < layers; ++l) {
    const glm::ivec4 r = rect[size_t(l)];
    if (r.z == 0) continue;
    program.set("u_layer", l);
    glScissor(r.x, r.y, r.z, r.w);
    glBindFramebuffer(GL_FRAMEBUFFER, fbos[size_t(l)].id());
    draw(l);
  }
  glDisable(GL_SCISSOR_TEST);
}

// One full-screen triangle per layer into fbos[l], u_layer = l.
void Stabilizer::Impl::per_layer(const gl::Program& program,
                                 const std::vector<gl::Framebuffer>& fbos) {
  program.use();
  glBindVertexArray(vao.id());
  glViewport(0, 0, width, height);
  each_layer(program, fbos, [](int) { glDrawArrays(GL_TRIANGLES, 0, 3); });
}

// Active tiles. Late in a relaxation only the pile edges still move, so the
// outflow and gather passes (and the routing's erosion passes) draw only the
// tiles (kTile x kTile columns) that may change, as instanced points of kTile
// pixels (one square per tile) from lists built on the GPU
// (stabilize_tiles.comp, no readback): one indirect draw per layer of the tiles
// where that layer has a surface, and for the gather pass, which computes a
// column's layers in one fragment, one draw of the tiles where any layer has
// one. A texel without a surface neither sends nor receives: its depth stays
// zero (cleared at the start; no pass adds snow there), and no pass reads its
// outflow or codes (the gather pass and the sums read only the layers with a
// surface, so the routing may leave its data there). The gather, apply and
// erosion passes stamp the tiles where a texel sent snow or changed with the
// pass index. A relaxation pass of stride s computes a tile when a tile within
// ceil(2 s / kTile) tiles (what its outflow reads, and what its inflow's
// outflow reads) was stamped at or after the last pass of stride s. A skipped
// tile is exact: its inputs are those of that last pass of the same stride,
// which moved no snow there, so its outflow is zero again (the outflow textures
// still hold the zeros of the last pass that computed it: a tile that moved
// snow is computed in the next pass) and its depth stays; both ping-pong depth
// textures hold the same depth there (it was computed and unchanged, or
// skipped, in the pass before). The largest move of a pass is zero in a skipped
// tile, so the gather's per-tile maximum is exact too. A strided pass moves
// only snow that single steps would move on the same depths
// (stabilize_outflow.frag), so the last pass of stride 1 serves as that last
// pass for every stride, when it came later: a tile stamped nowhere within
// reach since then sends nothing now, at any stride. After set_depth and
// add_snow (and the routing that follows, which uses the outflow textures as
// scratch) the first pass computes all tiles with a surface, and so does a
// strided pass before any pass of stride 1.
// Tiles of 4 x 4 columns are llvmpipe's shading blocks: larger tiles compute
// more columns that cannot change, smaller ones cost more points per pass
// (the sizes compared: tools/RESULTS.md).
// Erosion passes compute the tiles within one tile of a tile the previous
// erosion pass changed; no such tile ends the erosion (the same pass count as
// the occlusion-query check of the full passes). The routing's receiver pass
// computes the tiles its erosion passes stamped (the first also stamps snow
// pressed out under a ceiling: together every texel the routing moves), and
// stamps the tiles holding a routed texel; the pointer-jumping passes and the
// scatter draw only those, and the jump and apply passes take a texel of any
// other tile to point at itself (its pointer may not have been written).
void Stabilizer::Impl::select_tiles(const gl::Texture& stamps, int reach, int since, bool all) {
  // Per layer and for the column passes: one point per tile, no instances yet.
  std::vector<GLuint> commands(4 * size_t(layers + 1), 0);
  for (int l = 0; l <= layers; ++l) commands[4 * size_t(l)] = 1;
  glNamedBufferSubData(tile_list.id(), 0, GLsizeiptr(commands.size() * sizeof(GLuint)),
                       commands.data());
  glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);  // the stamps of the passes before
  bind_changed(stamps);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_STABILIZE_TILE_LIST, tile_list.id());
  bind(SNOW_STABILIZE_TILE_LAYERS, tile_layers);
  tile_select.use();
  tile_select.set("u_reach", reach);
  tile_select.set("u_since", since);
  tile_select.set("u_all", all ? 1 : 0);
  // One invocation per block of 8 x 8 tiles, in work groups of 8 x 8 blocks.
  glDispatchCompute(GLuint((tiles_x + 63) / 64), GLuint((tiles_y + 63) / 64), 1);
  glMemoryBarrier(GL_COMMAND_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT |
                  GL_BUFFER_UPDATE_BARRIER_BIT);
}

// The number of tiles the last select_tiles listed, over all layers (a
// readback; the column passes' list is not counted).
GLuint Stabilizer::Impl::selected_tiles() {
  std::vector<GLuint> commands(4 * size_t(layers));
  glGetNamedBufferSubData(tile_list.id(), 0, GLsizeiptr(commands.size() * sizeof(GLuint)),
                          commands.data());
  GLuint n = 0;
  for (int l = 0; l < layers; ++l) n += commands[4 * size_t(l) + 1];
  return n;
}

// Runs draw() with the tile lists bound for draw_tile_list.
template <class Draw>
void Stabilizer::Impl::with_tile_lists(Draw draw) {
  glBindBuffer(GL_DRAW_INDIRECT_BUFFER, tile_list.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_STABILIZE_TILE_LIST, tile_list.id());
  glViewport(0, 0, tiles_x * kTile, tiles_y * kTile);
  glEnable(GL_PROGRAM_POINT_SIZE);
  draw();
  glDisable(GL_PROGRAM_POINT_SIZE);
  glBindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
}

// One point per tile of list `list` (a layer, or `layers`: the tiles with
// any surface); the program's u_layer must name the same list.
void Stabilizer::Impl::draw_tile_list(int list) {
  glDrawArraysIndirect(GL_POINTS, reinterpret_cast<const void*>(sizeof(GLuint) * 4 * size_t(list)));
}

// As per_layer, drawing the listed tiles of each layer.
void Stabilizer::Impl::tiled_layers(const gl::Program& program,
                                    const std::vector<gl::Framebuffer>& fbos) {
  program.use();
  glBindVertexArray(vao.id());
  with_tile_lists([&] { each_layer(program, fbos, [&](int l) { draw_tile_list(l); }); });
}

// One fragment per column with a surface, for all its layers at once (the
// gather pass, which writes through images): with active tiles the tiles
// listed for any layer, else layer 0's rectangle (layers are packed, so it
// holds the others).
void Stabilizer::Impl::per_column(const gl::Program& program) {
  const glm::ivec4 r = rect[0];
  if (r.z == 0) return;
  program.use();
  glBindVertexArray(vao.id());
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_empty.id());
  glEnable(GL_SCISSOR_TEST);
  glScissor(r.x, r.y, r.z, r.w);
  if (tiled) {
    program.set("u_layer", layers);  // the list of tiles with any surface
    with_tile_lists([&] { draw_tile_list(layers); });
  } else {
    glViewport(0, 0, width, height);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }
  glDisable(GL_SCISSOR_TEST);
}

void Stabilizer::Impl::upload_depth(const std::vector<float>& d) {
  std::vector<glm::vec2> data(d.size());
  for (size_t k = 0; k < d.size(); ++k) data[k] = glm::vec2(d[k], 0.0f);
  write_depth(data);
}

void Stabilizer::Impl::write_depth(const std::vector<glm::vec2>& data) {
  glTextureSubImage3D(depth[cur].id(), 0, 0, 0, 0, width, height, layers, GL_RG, GL_FLOAT,
                      data.data());
  gl::check_error("stabilize: depth upload");
}

void Stabilizer::Impl::write_depth(const std::vector<float>& s, const std::vector<float>& lost) {
  std::vector<glm::vec2> data(s.size());
  for (size_t k = 0; k < data.size(); ++k) data[k] = glm::vec2(s[k], lost[k]);
  write_depth(data);
}

void Stabilizer::Impl::add_snow(const std::vector<float>& amount) {
  // The amount goes through out_a (scratch between passes) in r.
  glTextureSubImage3D(out_a.id(), 0, 0, 0, 0, width, height, layers, GL_RED, GL_FLOAT,
                      amount.data());
  add_pass(out_a, 1.0f);
}

void Stabilizer::Impl::add_pass(const gl::Texture& amount, float scale) {
  bind(SNOW_STABILIZE_CELLS, cells);
  bind(SNOW_STABILIZE_DEPTH, depth[cur]);
  bind(SNOW_STABILIZE_ADD, amount);
  glBindImageTexture(SNOW_STABILIZE_HOLD_IMAGE, holds.id(), 0, GL_TRUE, 0, GL_READ_WRITE, GL_RG32F);
  add.use();
  add.set("u_scale", scale);
  per_layer(add, fbo_depth[1 - cur]);
  cur = 1 - cur;
  glBindImageTexture(SNOW_STABILIZE_HOLD_IMAGE, 0, 0, GL_TRUE, 0, GL_READ_WRITE, GL_RG32F);
  glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
  release_bindings();
  gl::check_error("stabilize: add snow");
}

void Stabilizer::Impl::upload_holds(const std::vector<float>* depth) {
  const float stand = settings.cohesion.stand_height;
  std::vector<glm::vec2> data(hold_data.size());
  for (size_t k = 0; k < data.size(); ++k) {
    const float hold = hold_data[k];
    data[k] = glm::vec2(hold, depth ? std::min((*depth)[k], std::min(stand, hold)) : 0.0f);
  }
  glTextureSubImage3D(holds.id(), 0, 0, 0, 0, width, height, layers, GL_RG, GL_FLOAT, data.data());
  gl::check_error("stabilize: holds upload");
}

// Runs `program` over every layer into the attachment-less framebuffer
// and returns the fragments that were not discarded.
GLuint Stabilizer::Impl::count_fragments(const gl::Program& program) {
  glBeginQuery(GL_SAMPLES_PASSED, query.id());
  program.use();
  glBindVertexArray(vao.id());
  glViewport(0, 0, width, height);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_empty.id());
  glEnable(GL_SCISSOR_TEST);
  for (int l = 0; l < layers; ++l) {
    const glm::ivec4 r = rect[size_t(l)];
    if (r.z == 0) continue;
    program.set("u_layer", l);
    glScissor(r.x, r.y, r.z, r.w);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }
  glDisable(GL_SCISSOR_TEST);
  glEndQuery(GL_SAMPLES_PASSED);
  GLuint samples = 0;
  glGetQueryObjectuiv(query.id(), GL_QUERY_RESULT, &samples);
  return samples;
}

// Scatter (stabilize_scatter.*): the routed texels' excess summed into their
// terminals in out_a.r (cleared first), one point per layer texel of the
// tiles the receiver pass stamped (`routed` or later in tile_erode).
void Stabilizer::Impl::scatter_routed(int routed) {
  std::vector<GLint> stamps(size_t(tiles_x) * size_t(tiles_y));
  glGetTextureImage(tile_erode.id(), 0, GL_RED_INTEGER, GL_INT,
                    GLsizei(stamps.size() * sizeof(GLint)), stamps.data());
  const float zero[4] = {0, 0, 0, 0};
  glClearTexImage(out_a.id(), 0, GL_RGBA, GL_FLOAT, zero);
  scatter.use();
  glBindVertexArray(vao.id());
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_scatter.id());
  glViewport(0, 0, width, height);
  glEnable(GL_BLEND);
  glBlendEquation(GL_FUNC_ADD);
  glBlendFunc(GL_ONE, GL_ONE);
  // One point per layer texel of the stamped tiles in its layer's rectangle
  // (the texels elsewhere route nothing), in texel order: runs along rows,
  // joined across short gaps (a draw costs more than a few points on a
  // software rasterizer).
  constexpr GLint kJoinGap = 64;  // texels
  std::vector<GLint> firsts;
  std::vector<GLsizei> counts;
  for (int l = 0; l < layers; ++l) {
    const glm::ivec4 r = rect[size_t(l)];
    for (int y = r.y; y < r.y + r.w; ++y) {
      const GLint* row = &stamps[size_t(y / kTile) * size_t(tiles_x)];
      for (int tx = r.x / kTile; tx * kTile < r.x + r.z; ++tx) {
        if (row[tx] < routed) continue;
        const int x0 = std::max(tx * kTile, r.x), x1 = std::min((tx + 1) * kTile, r.x + r.z);
        const GLint start = GLint((size_t(l) * size_t(height) + size_t(y)) * size_t(width)) + x0;
        if (!firsts.empty() && start - (firsts.back() + counts.back()) <= kJoinGap) {
          counts.back() = start + (x1 - x0) - firsts.back();
        } else {
          firsts.push_back(start);
          counts.push_back(x1 - x0);
        }
      }
    }
  }
  if (!firsts.empty()) {
    glMultiDrawArrays(GL_POINTS, firsts.data(), counts.data(), GLsizei(firsts.size()));
  }
  glDisable(GL_BLEND);
}

int Stabilizer::Impl::route(Routing kind) {
  const bool drain = kind == Routing::Drain;
  const int repose_only = kind != Routing::Settle ? 1 : 0;
  bind(SNOW_STABILIZE_CELLS, cells);
  bind(SNOW_STABILIZE_HOLD, holds);
  bind(SNOW_STABILIZE_DEPTH, depth[cur]);
  // The routing runs in the outflow textures (r of each texel): the kept
  // heights ping-pong between out_b and code (as floats), the pointers
  // between the one of those two without the final kept heights (as
  // integers) and out_a (as integers), the scatter's target at the end.
  // Erosion until nothing changes; the kept height ends in stable_tex[e].
  const gl::Texture* stable_tex[2] = {&out_b, &code_float};
  const std::vector<gl::Framebuffer>* fbo_stable[2] = {&fbo_out_b, &fbo_code_float};
  // The stamps of this routing's passes are `first` and up (`first`: snow
  // pressed out under a ceiling, stamped by the first erosion pass).
  const int first = erode_counter++;
  bind_changed(tile_erode);
  int e = 0;
  int passes = 0;
  for (;;) {
    // The first pass starts from the depth and fills both textures.
    const int start = passes == 0 ? 1 : 0;
    const std::vector<gl::Framebuffer>& target = start ? fbo_stable_both : *fbo_stable[1 - e];
    bind(SNOW_STABILIZE_STABLE, *stable_tex[e]);
    if (tiled) {
      // All tiles first, then those next to a tile the previous pass changed.
      select_tiles(tile_erode, 1, erode_counter - 1, passes == 0);
      if (passes > 0 && selected_tiles() == 0) break;
      erode_tiled.set("u_pass", erode_counter);
      erode_tiled.set("u_start", start);
      erode_tiled.set("u_repose_only", repose_only);
      tiled_layers(erode_tiled, target);
    } else {
      erode.set("u_pass", erode_counter);
      erode.set("u_start", start);
      erode.set("u_repose_only", repose_only);
      per_layer(erode, target);
    }
    ++erode_counter;
    ++passes;
    e = 1 - e;
    if (!tiled) {
      bind(SNOW_STABILIZE_STABLE, *stable_tex[e]);
      bind(SNOW_STABILIZE_STABLE_OLD, *stable_tex[1 - e]);
      erode_check.set("u_start", start);
      erode_check.set("u_repose_only", repose_only);
      if (count_fragments(erode_check) == 0) break;
    }
    if (passes > 4 * (width + height) * layers + 16) {
      throw GLError("stabilize: routing erosion did not settle");
    }
  }
  if (drain) {
    // The excess fills and spills down its paths, on the CPU (snow/deposit.h,
    // as CpuStabilizer does) from the kept heights and the depth read back.
    std::vector<float> stable(size_t(width) * size_t(height) * size_t(layers));
    glGetTextureImage(stable_tex[e]->id(), 0, GL_RED, GL_FLOAT,
                      GLsizei(stable.size() * sizeof(float)), stable.data());
    gl::check_error("stabilize: kept heights readback");
    std::vector<float> s = read_channel(GL_RED), lost = read_channel(GL_GREEN);
    const float min_excess = routed_excess_of(settings, kind);
    if (!spill_excess(pour_cells.data(), stable.data(), s.data(), lost.data(),
                      DepositGrid{width, height, layers, grid.texel}, min_excess)
             .empty()) {
      write_depth(s, lost);
    }
    return passes;
  }
  bind(SNOW_STABILIZE_STABLE, *stable_tex[e]);
  const gl::Texture* pointer[2] = {e == 0 ? &code : &out_b_uint, &out_a_uint};
  const std::vector<gl::Framebuffer>* fbo_pointer[2] = {e == 0 ? &fbo_code : &fbo_out_b_uint,
                                                        &fbo_out_a_uint};
  // The receiver pass draws the tiles stamped since `first` (the others
  // hold no texel to route) and stamps those that hold a routed texel; the
  // later passes leave out the others, whose texels point at themselves.
  const int routed = erode_counter++;
  const float min_excess = routed_excess_of(settings, kind);
  if (tiled) {
    select_tiles(tile_erode, 0, first, false);
    receiver_tiled.set("u_pass", routed);
    receiver_tiled.set("u_min_excess", min_excess);
    tiled_layers(receiver_tiled, *fbo_pointer[0]);
  } else {
    receiver.set("u_pass", routed);
    receiver.set("u_min_excess", min_excess);
    per_layer(receiver, *fbo_pointer[0]);
  }
  glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT);
  glBindImageTexture(SNOW_STABILIZE_TILE_ROUTED, tile_erode.id(), 0, GL_FALSE, 0, GL_READ_ONLY,
                     GL_R32I);
  (tiled ? jump_tiled : jump).set("u_since", routed);
  if (tiled) select_tiles(tile_erode, 0, routed, false);
  int p = 0;  // pointer[p] holds the pointers
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_STABILIZE_JUMP_CHANGED, jump_changed.id());
  for (;;) {
    // A pass that moves no pointer on copies them: the chains have ended,
    // and that pass does not count.
    const GLuint zero = 0;
    glNamedBufferSubData(jump_changed.id(), 0, sizeof(zero), &zero);
    bind(SNOW_STABILIZE_POINTER, *pointer[p]);
    if (tiled) {
      tiled_layers(jump_tiled, *fbo_pointer[1 - p]);
    } else {
      per_layer(jump, *fbo_pointer[1 - p]);
    }
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    GLuint changed = 0;
    glGetNamedBufferSubData(jump_changed.id(), 0, sizeof(changed), &changed);
    if (changed == 0) break;
    p = 1 - p;
    ++passes;
    if (passes > 100000) throw GLError("stabilize: routing pointers did not settle");
  }
  // The last jump pass copied the pointers: read them from pointer[0], not
  // from out_a, which the scatter now clears and sums the routed snow into;
  // then apply.
  bind(SNOW_STABILIZE_POINTER, *pointer[0]);
  scatter_routed(routed);
  bind(SNOW_STABILIZE_OUT_A, out_a);
  bind_changed(tile_relax);
  apply.set("u_pass", pass_counter - 1);  // as a change of the last relaxation pass
  apply.set("u_since", routed);
  apply.set("u_add_arrive", settings.deposit_piles ? 0 : 1);
  per_layer(apply, fbo_depth[1 - cur]);
  cur = 1 - cur;
  if (settings.deposit_piles) {
    // The piles are poured on the CPU (snow/deposit.h), from the depth and
    // the scattered sums, as CpuStabilizer does; their tiles are computed
    // again by the first relaxation pass after the routing.
    std::vector<glm::vec2> data = read_depth();
    std::vector<float> s(data.size()), arrive(data.size());
    glGetTextureImage(out_a.id(), 0, GL_RED, GL_FLOAT, GLsizei(arrive.size() * sizeof(float)),
                      arrive.data());
    gl::check_error("stabilize: routed snow readback");
    for (size_t k = 0; k < data.size(); ++k) s[k] = data[k].x;
    if (deposit_piles(pour_cells.data(), s.data(), arrive.data(),
                      DepositGrid{width, height, layers, grid.texel}) > 0) {
      for (size_t k = 0; k < data.size(); ++k) data[k].x = s[k];
      write_depth(data);
    }
  }
  gl::check_error("stabilize: routing");
  return passes;
}

bool Stabilizer::Impl::pour_pressed() {
  // Most checks find nothing pressed: the depth alone is read, the lost snow
  // only to upload both after a pour.
  std::vector<float> s = read_channel(GL_RED);
  if (pour_pressed_snow(pour_cells.data(), s.data(), DepositGrid{width, height, layers, grid.texel},
                        settings.tolerance) == 0) {
    return false;
  }
  write_depth(s, read_channel(GL_GREEN));
  return true;
}

// One relaxation pass (outflow, then gather); with `measure`, the gather
// keeps the largest move per tile for largest_move().
void Stabilizer::Impl::relax_pass(int stride, bool measure) {
  int level = 0;
  while ((settings.max_stride >> level) > stride) ++level;
  bind(SNOW_STABILIZE_CELLS, cells);
  bind(SNOW_STABILIZE_HOLD, holds);
  bind(SNOW_STABILIZE_DEPTH, depth[cur]);
  const gl::Program& out_program = tiled ? outflow_tiled : outflow;
  const gl::Program& gather_program = tiled ? gather_tiled : gather;
  out_program.set("u_stride", stride);
  gather_program.set("u_stride", stride);
  gather_program.set("u_pass", pass_counter);
  gather_program.set("u_measure", measure ? 1 : 0);
  if (measure) {
    const GLuint zero = 0;
    glClearTexImage(tile_moves.id(), 0, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
    glClearTexImage(tile_void.id(), 0, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
    glClearTexImage(tile_seen.id(), 0, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
    glBindImageTexture(SNOW_STABILIZE_TILE_MOVES, tile_moves.id(), 0, GL_FALSE, 0, GL_READ_WRITE,
                       GL_R32UI);
    glBindImageTexture(SNOW_STABILIZE_TILE_VOID, tile_void.id(), 0, GL_FALSE, 0, GL_READ_WRITE,
                       GL_R32UI);
    glBindImageTexture(SNOW_STABILIZE_TILE_SEEN, tile_seen.id(), 0, GL_FALSE, 0, GL_READ_WRITE,
                       GL_R32UI);
  }
  if (tiled) {
    // Since the last pass of this stride or of stride 1, whichever came later
    // (a strided pass moves only what single steps move; "Active tiles").
    const int since = std::max(stride_last[size_t(level)], stride_last.back());
    select_tiles(tile_relax, (2 * stride + kTile - 1) / kTile, since, since < 0);
    if (settings.count_tiles) tiles_drawn += double(selected_tiles());
    tiled_layers(out_program, fbo_outflow);
  } else {
    per_layer(out_program, fbo_outflow);
  }
  bind(SNOW_STABILIZE_OUT_A, out_a);
  bind(SNOW_STABILIZE_OUT_B, out_b);
  bind(SNOW_STABILIZE_CODE, code);
  bind(SNOW_STABILIZE_COLUMN, column);
  bind_changed(tile_relax);
  glBindImageTexture(SNOW_STABILIZE_DEPTH_OUT, depth[1 - cur].id(), 0, GL_TRUE, 0, GL_WRITE_ONLY,
                     GL_RG32F);
  per_column(gather_program);
  // Its depth is read by texel fetches, readbacks and later draws into it.
  glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT |
                  GL_TEXTURE_UPDATE_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT);
  stride_last[size_t(level)] = pass_counter++;
  cur = 1 - cur;
}

void Stabilizer::Impl::request_moves(int slot) {
  if (!moves) {
    moves = gl::create_buffer();
    glNamedBufferStorage(moves.id(), kMoves * sizeof(GLuint), nullptr, GL_DYNAMIC_STORAGE_BIT);
    moves_read = gl::create_buffer();
    const GLbitfield flags = GL_MAP_READ_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
    glNamedBufferStorage(moves_read.id(), 2 * kMoves * sizeof(GLuint), nullptr, flags);
    moves_mapped = static_cast<const GLuint*>(
        glMapNamedBufferRange(moves_read.id(), 0, 2 * kMoves * sizeof(GLuint), flags));
    gl::check_error("stabilize: the moves' readback buffer");
    if (!moves_mapped) throw GLError("stabilize: cannot map the moves' readback buffer");
  }
  const GLuint zero = 0;
  glClearNamedBufferData(moves.id(), GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
  glBindImageTexture(SNOW_STABILIZE_TILE_MOVES, tile_moves.id(), 0, GL_FALSE, 0, GL_READ_ONLY,
                     GL_R32UI);
  glBindImageTexture(SNOW_STABILIZE_TILE_VOID, tile_void.id(), 0, GL_FALSE, 0, GL_READ_ONLY,
                     GL_R32UI);
  glBindImageTexture(SNOW_STABILIZE_TILE_SEEN, tile_seen.id(), 0, GL_FALSE, 0, GL_READ_ONLY,
                     GL_R32UI);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, SNOW_STABILIZE_MOVES, moves.id());
  moves_reduce.use();
  glDispatchCompute(GLuint((tiles_x + 7) / 8), GLuint((tiles_y + 7) / 8), 1);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
  glCopyNamedBufferSubData(moves.id(), moves_read.id(), 0, GLintptr(slot) * kMoves * sizeof(GLuint),
                           kMoves * sizeof(GLuint));
  if (moves_fence[slot]) glDeleteSync(moves_fence[slot]);
  moves_fence[slot] = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  glFlush();
  gl::check_error("stabilize: asking for the largest moves");
}

glm::vec3 Stabilizer::Impl::read_moves(int slot) {
  while (glClientWaitSync(moves_fence[slot], GL_SYNC_FLUSH_COMMANDS_BIT, 1000000000) ==
         GL_TIMEOUT_EXPIRED) {
  }
  glDeleteSync(moves_fence[slot]);
  moves_fence[slot] = nullptr;
  glm::vec3 result;
  std::memcpy(&result[0], &moves_mapped[kMoves * slot], kMoves * sizeof(float));
  return result;
}

void Stabilizer::Impl::drop_pending() { pending_slot = -1; }

std::optional<glm::vec3> Stabilizer::Impl::checked_moves(int stride, int& measured_stride) {
  measured_stride = stride;
  if (!async_checks) return largest_move();
  const int slot = pending_slot == 0 ? 1 : 0;
  request_moves(slot);
  std::optional<glm::vec3> before;
  if (pending_slot >= 0) {
    measured_stride = pending_stride;
    before = read_moves(pending_slot);
  }
  pending_slot = slot;
  pending_stride = stride;
  return before;
}

glm::dvec3 Stabilizer::Impl::sum_blocks() {
  bind(SNOW_STABILIZE_DEPTH, depth[cur]);
  bind(SNOW_STABILIZE_OUT_A, out_a);
  bind(SNOW_STABILIZE_COLUMN, column);
  sums.use();
  glBindVertexArray(vao.id());
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_reduce.id());
  glViewport(0, 0, reduce_width, reduce_height);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  std::vector<glm::vec4> blocks(size_t(reduce_width) * size_t(reduce_height));
  glGetTextureImage(reduce.id(), 0, GL_RGBA, GL_FLOAT, GLsizei(blocks.size() * sizeof(glm::vec4)),
                    blocks.data());
  gl::check_error("stabilize: snow sums");
  glm::dvec3 r(0.0);
  for (const glm::vec4& b : blocks) r += glm::dvec3(b);
  return r;
}

glm::vec3 Stabilizer::Impl::largest_move() const {
  glm::vec3 result;
  std::vector<GLuint> moves(size_t(tiles_x) * size_t(tiles_y));
  const gl::Texture* tiles[kMoves] = {&tile_moves, &tile_void, &tile_seen};
  for (int which = 0; which < kMoves; ++which) {
    glGetTextureImage(tiles[which]->id(), 0, GL_RED_INTEGER, GL_UNSIGNED_INT,
                      GLsizei(moves.size() * sizeof(GLuint)), moves.data());
    gl::check_error("stabilize: largest move");
    GLuint largest = 0;  // the bits of non-negative floats order as the floats
    for (GLuint m : moves) largest = std::max(largest, m);
    std::memcpy(&result[which], &largest, sizeof(float));
  }
  return result;
}

// One channel of the depth texture (GL_RED: depth, GL_GREEN: lost), half the
// memory of read_depth.
std::vector<float> Stabilizer::Impl::read_channel(GLenum channel) const {
  std::vector<float> data(count());
  glGetTextureImage(depth[cur].id(), 0, channel, GL_FLOAT, GLsizei(data.size() * sizeof(float)),
                    data.data());
  gl::check_error("stabilize: depth readback");
  return data;
}

std::vector<glm::vec2> Stabilizer::Impl::read_depth() const {
  std::vector<glm::vec2> data(count());
  glGetTextureImage(depth[cur].id(), 0, GL_RG, GL_FLOAT, GLsizei(data.size() * sizeof(glm::vec2)),
                    data.data());
  gl::check_error("stabilize: depth readback");
  return data;
}

void Stabilizer::Impl::route_into(Routing kind, double lost_before, StabilizeResult& result) {
  const auto t0 = std::chrono::steady_clock::now();
  result.route_passes += route(kind);
  // Routed = scattered to terminals (out_a.r) + routed into the void.
  const glm::dvec3 after = sum_blocks();
  const double area = double(grid.texel) * double(grid.texel);
  result.routed_volume += (after.z + after.y) * area - lost_before;
  result.route_seconds += seconds_since(t0);
}

StabilizeResult Stabilizer::Impl::iterate(int passes) {
  StabilizeResult result;
  const double area = double(grid.texel) * double(grid.texel);
  const bool routes = route_pending && settings.route_steep;
  const double lost_before = lost_is_zero || !(volume_sums || routes) ? 0.0 : sum_blocks().y * area;
  lost_is_zero = false;
  if (route_pending) {
    if (settings.route_steep) route_into(Routing::Settle, lost_before, result);
    route_pending = false;
    reset_tiles();
  }
  tiles_drawn = 0.0;
  int last_check = 0;
  for (int pass = 1; pass <= passes; ++pass) {
    const int stride = schedule.next();
    const bool check = (stride == 1 && pass - last_check >= settings.check_every) || pass == passes;
    relax_pass(stride, check);
    ++result.iterations;
    if (check) {
      last_check = pass;
      int measured_stride = stride;
      const std::optional<glm::vec3> measured = checked_moves(stride, measured_stride);
      if (!measured) continue;  // the first asynchronous check: nothing known yet
      const glm::vec3 moves = *measured;
      result.residual = moves.z;
      schedule.checked(measured_stride, moves.x);
      // A strided pass's largest move says nothing of single steps (its
      // paths may be blocked where single steps still move snow).
      if (measured_stride == 1 && moves.z < settings.tolerance) {
        result.converged = true;
        break;
      }
      run_check_routings(
          settings, schedule, async_checks, moves.x, moves.y, result,
          [&] {
            route_into(Routing::Creep, sum_blocks().y * area, result);
            reset_tiles();  // the routing used the outflow textures
          },
          [&] {
            if (!pour_pressed()) return false;
            reset_tiles();
            return true;
          },
          [&] {
            result.route_passes += route(Routing::Drain);
            reset_tiles();  // the routing used the outflow textures
          });
    }
  }
  if (volume_sums) {
    const glm::dvec3 totals = sum_blocks();
    result.volume = totals.x * area;
    result.lost_volume = totals.y * area - lost_before;
  }
  release_bindings();
  result.tile_share = !tiled ? 1.0
                      : settings.count_tiles && result.iterations > 0
                          ? tiles_drawn / (double(result.iterations) * tiles_x * tiles_y * layers)
                          : 0.0;
  return result;
}

Stabilizer::Stabilizer(const SnowMaps& maps, const StabilizeSettings& settings)
    : impl_(std::make_unique<Impl>(maps, settings)) {}
Stabilizer::~Stabilizer() = default;
Stabilizer::Stabilizer(Stabilizer&&) noexcept = default;
Stabilizer& Stabilizer::operator=(Stabilizer&&) noexcept = default;

void Stabilizer::set_depth(const std::vector<float>& depth) {
  if (depth.size() != impl_->count()) {
    throw InputError("stabilize: depth has " + std::to_string(depth.size()) +
                     " entries, the maps have " + std::to_string(impl_->count()) + " layer texels");
  }
  std::vector<float> clean(depth.size());
  for (size_t k = 0; k < depth.size(); ++k) {
    clean[k] = impl_->surface[k] && depth[k] > 0.0f ? depth[k] : 0.0f;
  }
  impl_->upload_depth(clean);  // lost (g) = 0
  impl_->upload_holds(&clean);
  impl_->drop_pending();
  impl_->route_pending = true;
  impl_->reset_tiles();
  impl_->schedule.restart();
  impl_->lost_is_zero = true;
}

void Stabilizer::add_snow(const std::vector<float>& amount, float scale) {
  if (amount.size() != impl_->count()) {
    throw InputError("stabilize: snow amount has " + std::to_string(amount.size()) +
                     " entries, the maps have " + std::to_string(impl_->count()) + " layer texels");
  }
  std::vector<float> add(amount.size());
  for (size_t k = 0; k < amount.size(); ++k) {
    const float a = amount[k] * scale;
    add[k] = impl_->surface[k] && a > 0.0f ? a : 0.0f;  // NaN and negative add nothing
  }
  impl_->add_snow(add);
  impl_->drop_pending();
  impl_->route_pending = true;
  impl_->reset_tiles();
  impl_->schedule.restart();
}

void Stabilizer::set_snow_amount(const std::vector<float>& amount) {
  Impl& m = *impl_;
  if (amount.size() != m.count()) {
    throw InputError("stabilize: snow amount has " + std::to_string(amount.size()) +
                     " entries, the maps have " + std::to_string(m.count()) + " layer texels");
  }
  std::vector<float> kept(amount.size());
  for (size_t k = 0; k < amount.size(); ++k)
    kept[k] = m.surface[k] && amount[k] > 0.0f ? amount[k] : 0.0f;  // NaN and negative: 0
  if (!m.kept_amount)
    m.kept_amount =
        gl::create_texture_2d_array(GL_R32F, m.width, m.height, m.layers, "stabilize snow amount");
  glTextureSubImage3D(m.kept_amount.id(), 0, 0, 0, 0, m.width, m.height, m.layers, GL_RED, GL_FLOAT,
                      kept.data());
  gl::check_error("stabilize: keeping the snow amount");
}

void Stabilizer::add_snow(float scale) {
  if (!impl_->kept_amount) return;
  impl_->add_pass(impl_->kept_amount, scale);
  impl_->drop_pending();
  impl_->route_pending = true;
  impl_->reset_tiles();
  impl_->schedule.restart();
}

StabilizeResult Stabilizer::iterate(int passes) { return impl_->iterate(std::max(0, passes)); }

void Stabilizer::set_volume_sums(bool on) { impl_->volume_sums = on; }

void Stabilizer::set_async_checks(bool on) {
  impl_->async_checks = on;
  impl_->drop_pending();
}

StabilizeResult Stabilizer::run() {
  const double before = impl_->lost_is_zero ? 0.0 : lost_volume();
  StabilizeResult result = impl_->iterate(impl_->settings.max_iterations);
  const std::vector<glm::vec2> data = impl_->read_depth();
  double depth_sum = 0.0, lost_sum = 0.0;
  for (const glm::vec2& d : data) {
    depth_sum += double(d.x);
    lost_sum += double(d.y);
  }
  const double area = double(impl_->grid.texel) * double(impl_->grid.texel);
  result.volume = depth_sum * area;
  result.lost_volume = lost_sum * area - before;
  return result;
}

std::vector<float> Stabilizer::depth() const { return impl_->read_channel(GL_RED); }

double Stabilizer::lost_volume() const {
  double sum = 0.0;
  for (float lost : impl_->read_channel(GL_GREEN)) sum += double(lost);
  return sum * double(impl_->grid.texel) * double(impl_->grid.texel);
}

unsigned Stabilizer::depth_texture() const { return impl_->depth[impl_->cur].id(); }
const MapGrid& Stabilizer::grid() const { return impl_->grid; }
int Stabilizer::layers() const { return impl_->layers; }
const StabilizeSettings& Stabilizer::settings() const { return impl_->settings; }

}  // namespace snow
