// The filters pipeline's uniforms (paper 004), its per-pixel layer record and the step each
// dispatch belongs to.

struct Filters {
    // The eye; a pixel's ray is forward + ndc.x * right + ndc.y * up, so that the point at
    // linear depth d along it is eye + d * ray.
    eye: vec4<f32>,
    forward: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    // w 0: the headlight; w 1: xyz is the unit direction towards a light fixed in the world.
    light: vec4<f32>,
    // Opacity of a point of class c: class_opacity[c / 4][c % 4] (classes from CLASSES on: [0].x
    // is not used for them, see `point_opacity`).
    class_opacity: array<vec4<f32>, 5>,
    // The minimum distance between two surface layers (section 3.3), in dataset units.
    dtilde: f32,
    // 1: the points carry normals (the resolve reads them; else the shade, compiled with
    // ESTIMATE_NORMALS, estimates them from the filled depth).
    normals: u32,
    // The opacity of classes without an entry of their own.
    opacity: f32,
    // 1 / the light samples summed in each point's lit count; 0: no shadows (every point lit).
    lit_scale: f32,
    pad0: f32,
    pad1: f32,
    pad2: f32,
    pad3: f32,
}

@group(0) @binding(1) var<uniform> fil: Filters;

// Classes with an opacity of their own (the ASPRS standard classes 0 to 18).
const CLASSES: u32 = 19u;

// What one dispatch works on: its layer and fill iteration, and for the resolve whether its
// depth and index planes hold complements (the peeled layers) or the projection's planes.
struct Step {
    layer: u32,
    iteration: u32,
    // ARGS_*: the layer's passes, or a fill's kind.
    kind: u32,
    complemented: u32,
}

const ARGS_LAYER: u32 = 0u;
const ARGS_BACKGROUND: u32 = 1u;
const ARGS_OCCLUDED: u32 = 2u;

// Layers at most; fill iterations at most (per kind and layer).
const MAX_LAYERS: u32 = 8u;
const MAX_ITERATIONS: u32 = 16u;
// The counters: per layer 1 where it holds a pixel, then per layer, kind and iteration 1 where
// the iteration changed a pixel.
const COUNTERS: u32 = 264u;

fn changed_slot(layer: u32, kind: u32, iteration: u32) -> u32 {
    return MAX_LAYERS + (layer * 2u + kind - 1u) * MAX_ITERATIONS + iteration;
}

// One pixel of a layer: x linear depth bits (0: background, as in the paper), y colour (RGBA8,
// alpha the opacity), z the normal (oct16, world space, facing the eye), w: bit 0 set where z
// holds one, bits 1 to 5 the texel's reach (`texel_reach`), bit 6 set where the background
// fill carried it there, bits 16 to 31 the share of the light that reaches the point (unorm16).
alias Texel = vec4<u32>;

// The fill's 16x16 tiles: per row, per column, and the flag of `tile` for a fill kind
// (ARGS_BACKGROUND or ARGS_OCCLUDED) and iteration.
fn tiles_x() -> u32 {
    return (frame.width + 15u) / 16u;
}

fn tiles_y() -> u32 {
    return (frame.height + 15u) / 16u;
}

fn tile_slot(kind: u32, iteration: u32, tile: vec2<u32>) -> u32 {
    return ((kind - 1u) * MAX_ITERATIONS + iteration) * tiles_x() * tiles_y() + tile.y * tiles_x() + tile.x;
}

// The fill's tile lists, one per kind and iteration. List k starts at word list_base(k):
// LIST_HEADER words, the arguments of its iteration's indirect dispatch (x, y, 1: x * y
// workgroups at least as many as its tiles, 0, 0, 0 while it has none) and its count; then the
// tiles, y << 16 | x.
const LIST_HEADER: u32 = 4u;
// Workgroups a dispatch takes in x at most (WebGPU's least maximum per dimension).
const MAX_GROUPS_X: u32 = 65535u;
const LISTS: u32 = 2u * MAX_ITERATIONS;

fn list_of(kind: u32, iteration: u32) -> u32 {
    return (kind - 1u) * MAX_ITERATIONS + iteration;
}

fn list_base(list: u32) -> u32 {
    return list * (LIST_HEADER + tiles_x() * tiles_y());
}

// After every kind's and iteration's flags: per tile, 1 where the layer's resolve put a point in
// it (the first layer's first fill iterations work only on those tiles and the ones beside).
fn occupied_slot(tile: vec2<u32>) -> u32 {
    return 2u * MAX_ITERATIONS * tiles_x() * tiles_y() + tile.y * tiles_x() + tile.x;
}

// How many pixels further the background fill may still carry the texel: the widest hole its
// point's sampling can leave (resolve.wgsl), less the pixels it was carried already.
const MAX_REACH_PX: u32 = 31u;

const CARRIED: u32 = 64u;

fn texel_reach(t: Texel) -> u32 {
    return reach_of(t.w);
}

// The reach in a texel's flags word (its w).
fn reach_of(w: u32) -> u32 {
    return (w >> 1u) & MAX_REACH_PX;
}

fn with_reach(w: u32, reach: u32) -> u32 {
    return (w & ~(MAX_REACH_PX << 1u)) | (min(reach, MAX_REACH_PX) << 1u);
}

fn texel_lit(t: Texel) -> f32 {
    return f32(t.w >> 16u) / 65535.0;
}

fn with_lit(w: u32, lit: f32) -> u32 {
    return (w & 0xffffu) | (u32(clamp(lit, 0.0, 1.0) * 65535.0 + 0.5) << 16u);
}

fn encode_oct16(n: vec3<f32>) -> u32 {
    var p = n.xy / (abs(n.x) + abs(n.y) + abs(n.z));
    if n.z < 0.0 {
        let s = select(vec2<f32>(-1.0), vec2<f32>(1.0), p >= vec2<f32>(0.0));
        p = (1.0 - abs(p.yx)) * s;
    }
    return pack2x16unorm(p * 0.5 + 0.5);
}
