// Shared by every pass: the per-frame uniforms and the per-arena range table.

struct Frame {
    view_proj: mat4x4<f32>,
    width: u32,
    height: u32,
    point_size: f32,
    // 0: point_size is in pixels; 1: point_size multiplies the node's point spacing.
    size_mode: u32,
    focal_px: f32,
    colour_mode: u32,
    z_min: f32,
    z_max: f32,
    arena_shift: u32,
    background: u32,
    // Clip boxes in `clip_boxes`.
    clip_count: u32,
    // Points are drawn at least footprint * their radius across (the Radius stream, group 1
    // binding 4 of the projection); 0: never read.
    footprint: f32,
    // The chosen pipeline's own shading parameters (its `Pipeline::uniforms` sets them; the edl
    // shading reads strength in x and radius in y).
    shading: vec4<f32>,
    // Arena of each of the fused finish pass's four binding slots.
    arena_slots: vec4<u32>,
    // Colouring by intensity: 1 / the intensity shown at full brightness.
    intensity_scale: f32,
    // Which filters apply (FILTER_* bits); 0: every point passes.
    filters: u32,
    return_lo: u32,
    return_hi: u32,
    // Intensity from x to y, elevation (relative to the anchor) from z to w.
    ranges: vec4<f32>,
    // Classes shown: bit c of word c / 32.
    class_mask: array<vec4<u32>, 2>,
    // Box k: minimum in [2k].xyz (w 1: hides its inside, 0: keeps it), maximum in [2k + 1].xyz;
    // relative to the anchor.
    clip_boxes: array<vec4<f32>, 8>,
    // The eye, relative to the anchor (the projection's back-face culling and footprint).
    eye: vec4<f32>,
    // 1: the facing check found the stored normals pointing into the surfaces (facing.rs),
    // and each is turned before use (`normal_sign`); 0: as stored.
    normals_turned: u32,
    // The linear depths drawn (`in_depth_range`).
    near: f32,
    far: f32,
}

// Whether a point whose clip position is `clip` lies between the near and far planes (the
// frame's `near` and `far`): its linear depth (clip.w) compared with theirs. That holds at any
// ratio of far to near (clip.w is as precise as the position it comes from), where the
// matrix's depth (clip.z against clip.w) loses the far end in f32 beyond a ratio of about 1e5.
fn in_depth_range(clip: vec4<f32>, near: f32, far: f32) -> bool {
    return clip.w >= near && clip.w <= far;
}

const FILTER_CLASSES: u32 = 1u;
const FILTER_INTENSITY: u32 = 2u;
const FILTER_ELEVATION: u32 = 4u;
const FILTER_RETURN: u32 = 8u;
const FILTER_CLIP: u32 = 16u;
const FILTER_MARKED: u32 = 32u;

// The GPU attribute word: intensity (16 bits), classification (8), return number (4), then
// MARK_HIDDEN: outside a range of an attribute the word does not hold (marks.rs), and
// RETURN_ABOVE_15: a return number the four bits cannot hold.
const MARK_HIDDEN: u32 = 0x10000000u;
const RETURN_ABOVE_15: u32 = 0x80000000u;
fn attribute_class(a: u32) -> u32 {
    return (a >> 16u) & 0xffu;
}

// ranges[0] is a header: start = arena index, count = number of ranges that follow.
struct Range {
    start: u32,
    count: u32,
    first_group: u32,
    spacing: f32,
    // The node's centre, relative to the anchor.
    centre: vec3<f32>,
    // Bit k: the child in octant k (x 4, y 2, z 1) is drawn too; bit 8 + k: the dataset has
    // it; bit 16 + k: it and every node below it are drawn, down to the leaves.
    children: u32,
}

// The radius to draw point `p` of range `r` with, `stored` its Radius stream's value (0: none;
// SPEC.md section 4). Where the LOD stopped at the point's node, the point stands for the
// points its descendants would add: at least its node's spacing wide, so that stopping leaves
// no hole. Where the node's child in the point's octant is drawn, the point fills the cell of
// the child's grid it was taken from: at least the child's spacing. Where every point the
// dataset has there is drawn (no child there, or the child's whole subtree drawn), the stored
// radius measures the sampling around the point (often far finer than the level's spacing,
// which spilled past a surface's edges as scallops); the spacing stands in where none is
// stored.
fn drawn_radius(r: Range, p: vec3<f32>, stored: f32) -> f32 {
    let rel = p - r.centre;
    let octant = select(0u, 4u, rel.x >= 0.0) | select(0u, 2u, rel.y >= 0.0) | select(0u, 1u, rel.z >= 0.0);
    let below = (r.children & (1u << octant)) != 0u;
    let exists = (r.children & (256u << octant)) != 0u;
    let all_below = (r.children & (65536u << octant)) != 0u;
    if stored > 0.0 && (!exists || (below && all_below)) {
        return stored;
    }
    return max(stored, select(r.spacing, 0.5 * r.spacing, below));
}

const EMPTY: u32 = 0xffffffffu;
const GROUP_SIZE: u32 = 256u;
