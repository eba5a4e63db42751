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
    pad0: u32,
    pad1: u32,
    // The chosen pipeline's own shading parameters (its `Pipeline::uniforms` sets them; the edl
    // shading reads strength in x and radius in y).
    shading: vec4<f32>,
    // Arena of each of the fused finish pass's four binding slots.
    arena_slots: vec4<u32>,
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
