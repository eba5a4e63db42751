// The triangulation's own uniforms, read by all its passes.

struct Triangulate {
    // This frame's eye and pixel rays: the point at linear depth d on the ray through
    // normalised device coordinates (x, y) is eye + d * (forward + x * right + y * up).
    eye: vec4<f32>,
    forward: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    // The previous frame's, for the reprojection of its reconstructed depth.
    prev_eye: vec4<f32>,
    prev_forward: vec4<f32>,
    prev_right: vec4<f32>,
    prev_up: vec4<f32>,
    // The largest search radius (dataset units), but see `connection_limit` (rays.wgsl).
    max_connection: f32,
    // Node spacings a connection may span where `max_connection` is automatic (else 0).
    spacing_factor: f32,
    // 1: the previous frame's depth exists and the reprojection ran.
    previous: u32,
    // The largest search splat, in pixels either side of the point.
    max_search_px: u32,
    // 1: a point that has a normal of its own (the dataset's, which the gather keeps) is shaded
    // with it; 0, or a point without one: with its fan's (the paper's, `normals.wgsl`).
    stored_normals: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// The dataset's normals tell a surface's two sides apart (`normals_mark_back_faces`): the
// gather keeps each pixel's normal, the search joins no two points on opposite sides, and the
// raster blends the fans facing away apart, which the shade shows only where no front face
// drew. An override, so that the passes without it hold none of its code
// (`ShaderSource::constants`); they bind the same buffers.
override SIDES: bool = false;

// Sectors around a point (Figure 3), in circular order.
const SECTORS: u32 = 8u;
// The blend sums of colour and normal over a pixel's fragments (raster_sums*.wgsl adds, and
// shade_sums*.wgsl reads, one of two layouts). 32-bit: SUM_WORDS words a pixel (fragment
// weight, r, g, b, nx, ny, nz), each fragment weighing FRAGMENT_WEIGHT.
const SUM_WORDS: u32 = 7u;
const FRAGMENT_WEIGHT: u32 = 16u;
// 64-bit: SUM64_WORDS words a pixel, r, g, b of SUM64_COLOUR_BITS each and the fragment count
// above them, then nx, ny, nz of SUM64_NORMAL_BITS each; a fragment adds colour and normal in
// units of 1 / SUM64_COLOUR_SCALE and 1 / SUM64_NORMAL_SCALE. A pixel keeps its first
// SUM64_KEPT fragments, so no field can overflow into the next: 512 x 255 < 2^17 and
// 512 x 4095 < 2^21.
const SUM64_WORDS: u32 = 2u;
const SUM64_COLOUR_BITS: u32 = 17u;
const SUM64_COUNT_SHIFT: u32 = 51u;
const SUM64_NORMAL_BITS: u32 = 21u;
const SUM64_COLOUR_SCALE: f32 = 255.0;
const SUM64_NORMAL_SCALE: f32 = 4095.0;
const SUM64_KEPT: u32 = 512u;

// A pixel's blend of the fragments drawn on it: their count, and the means of their colour
// and of their normal mapped from [-1, 1] to [0, 1].
struct Blend {
    fragments: u32,
    colour: vec3<f32>,
    normal: vec3<f32>,
}
// A triangle wider or taller than this many pixels is not drawn: its corners are a point and
// two of its neighbours, each within the point's search splat (at most 47 pixels either side),
// so only a triangle seen edge-on across a depth gap, or behind the eye, exceeds it.
const MAX_TRIANGLE_PX: f32 = 96.0;

// The sector of screen offset (dx, dy) (pixels, y down), counter-clockwise on screen from +x:
// sector k holds the angles [k, k + 1) times 45 degrees, a direction on a boundary the sector it
// starts. By comparisons, not atan2: the search takes it for every pixel of every point's splat
// (on lavapipe atan2's rounding also put 135 and 180 degrees in the sector before).
fn sector_of(dx: f32, dy: f32) -> u32 {
    let x = dx;
    let y = -dy;
    // The upper half, [0, 180) degrees; the lower one turned half a turn onto it.
    let upper = y > 0.0 || (y == 0.0 && x > 0.0);
    let u = select(-x, x, upper);
    let v = select(-y, y, upper);
    let quarter = select(select(3u, 2u, v > -u), select(1u, 0u, v < u), u > 0.0);
    return quarter + select(4u, 0u, upper);
}
