// Shared by the passes of the pyramid pipeline (paper 003): its uniforms, its buffers and the
// conversions between pixels, depths and view-space points. Every level of a pyramid lives in
// one buffer; `pyr.table[l]` gives the level's offset, width and height.

// Pyramid levels at most (`MAX_LEVELS` in passes.rs).
const MAX_LEVELS: u32 = 16u;

struct Pyramid {
    // Level-0 pixel coordinates to view-space x/y at depth 1: px * pixel_scale + pixel_bias.
    pixel_scale: vec2<f32>,
    pixel_bias: vec2<f32>,
    far: f32,
    // s_hpr * focal length in pixels: the HPR neighbourhood level at depth z is log2(hpr_scale / z).
    hpr_scale: f32,
    // The same for the normal estimation radius.
    normal_scale: f32,
    threshold: f32,
    levels: u32,
    coarse_level: u32,
    s0: f32,
    // The depth noise's normal level at depth z is 0.5 log2(noise_scale / z); written on the
    // GPU by the noise estimate each frame, 0 before it.
    noise_scale: f32,
    // s0 * focal length in pixels / DENSE_SPACING_PX: below 1 at depth z (dense_scale / z),
    // the points there lie too close to leave a hole wider than a pixel.
    dense_scale: f32,
    // 1: the dataset's normals, seeded per pixel (pyramid_stored.wgsl), are carried through the
    // pull-push in `normals` and shade; the pyramid's own from depth are not estimated.
    stored_normals: u32,
    // The pyramid level the stored normals are averaged at for their noise (pyramid_noise.wgsl);
    // written on the GPU each frame, 0 before it.
    stored_level: f32,
    pad2: f32,
    // The direction towards a light fixed in the world, in view space (0: the headlight);
    // w: 1 where the shading is Blinn-Phong with the lit share (a world light or shadows),
    // 0 for the plain two-sided headlight.
    light: vec4<f32>,
    // The rows of the view's rotation: world directions to view space.
    view_rows: array<vec4<f32>, 3>,
    table: array<vec4<u32>, MAX_LEVELS>,
}

struct Level {
    index: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> pyr: Pyramid;
@group(0) @binding(2) var<uniform> level: Level;
// The projection's nearest depth per pixel and the colour resolved for it.
@group(1) @binding(0) var<storage, read> depths: array<u32>;
@group(1) @binding(1) var<storage, read> colours: array<u32>;
// Min-depth point pyramid: (depth bits, level-0 pixel of the point as x | y << 16).
@group(1) @binding(2) var<storage, read_write> pts: array<vec2<u32>>;
// Pull-push pyramid: (depth, weight) and colour.
@group(1) @binding(3) var<storage, read_write> fill: array<vec2<f32>>;
@group(1) @binding(4) var<storage, read_write> fill_colour: array<u32>;
// Normal pyramid, octahedral-encoded; 0 where a level has no surface. With `stored_normals`,
// the dataset's normals, pulled and pushed like colour.
@group(1) @binding(5) var<storage, read_write> normals: array<u32>;
// Per pixel: LABEL_POINT, LABEL_HOLE or LABEL_BACKGROUND.
@group(1) @binding(6) var<storage, read_write> labels: array<u32>;
// Per pixel, the shaded surface: (depth bits or EMPTY, octahedral normal).
@group(1) @binding(7) var<storage, read_write> surface: array<vec2<u32>>;
@group(1) @binding(8) var output: texture_storage_2d<rgba8unorm, write>;

const LABEL_POINT: u32 = 0u;
const LABEL_HOLE: u32 = 1u;
const LABEL_BACKGROUND: u32 = 2u;
const NO_NORMAL: u32 = 0u;

fn level_offset(l: u32) -> u32 {
    return pyr.table[l].x;
}

fn level_size(l: u32) -> vec2<u32> {
    return pyr.table[l].yz;
}

// The view-space point at level-0 pixel coordinates `px` (pixel centres at .5) and linear depth d.
fn view_point(px: vec2<f32>, d: f32) -> vec3<f32> {
    return vec3<f32>((px * pyr.pixel_scale + pyr.pixel_bias) * d, -d);
}

// 16 bits a coordinate: no adapter allows textures 65536 pixels wide.
fn pack_pixel(p: vec2<u32>) -> u32 {
    return p.x | (p.y << 16u);
}

// The view-space point of a point-pyramid entry. The pixel is packed, not a linear index: the
// HPR pass unpacks eight of them per level per pixel, and a division costs far more than a shift.
fn entry_point(e: vec2<u32>) -> vec3<f32> {
    let p = vec2<f32>(vec2<u32>(e.y & 0xffffu, e.y >> 16u)) + 0.5;
    return view_point(p, bitcast<f32>(e.x));
}

fn oct_wrap(v: vec2<f32>) -> vec2<f32> {
    return (1.0 - abs(v.yx)) * select(vec2<f32>(-1.0), vec2<f32>(1.0), v >= vec2<f32>(0.0));
}

fn encode_normal(n: vec3<f32>) -> u32 {
    var p = n.xy / (abs(n.x) + abs(n.y) + abs(n.z));
    if n.z < 0.0 {
        p = oct_wrap(p);
    }
    // Never NO_NORMAL: (0, 0) encodes to a non-zero pattern.
    return pack2x16snorm(p) | select(0u, 1u, pack2x16snorm(p) == NO_NORMAL);
}

fn decode_normal(e: u32) -> vec3<f32> {
    let p = unpack2x16snorm(e);
    var n = vec3<f32>(p, 1.0 - abs(p.x) - abs(p.y));
    if n.z < 0.0 {
        n = vec3<f32>(oct_wrap(n.xy), n.z);
    }
    return normalize(n);
}
