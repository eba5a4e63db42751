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
    pad1: u32,
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
    // The eye, relative to the anchor (the projection's back-face culling).
    eye: vec4<f32>,
}

const FILTER_CLASSES: u32 = 1u;
const FILTER_INTENSITY: u32 = 2u;
const FILTER_ELEVATION: u32 = 4u;
const FILTER_RETURN: u32 = 8u;
const FILTER_CLIP: u32 = 16u;
const FILTER_MARKED: u32 = 32u;

// The GPU attribute word: intensity (16 bits), classification (8), return number (4), then
// MARK_HIDDEN: outside a range of an attribute the word does not hold (marks.rs).
const MARK_HIDDEN: u32 = 0x10000000u;
fn attribute_class(a: u32) -> u32 {
    return (a >> 16u) & 0xffu;
}

// ranges[0] is a header: start = arena index, count = number of ranges that follow.
struct Range {
    start: u32,
    count: u32,
    first_group: u32,
    spacing: f32,
}

const EMPTY: u32 = 0xffffffffu;
const GROUP_SIZE: u32 = 256u;
