// Eye-dome lighting: darkens pixels whose eight neighbours (at the radius) are nearer, by the
// log-depth differences. Needs `pixel_depth(i)` from the including pass.

const NO_DEPTH: f32 = -1e30;
// Eight neighbours at 45 degree steps on the unit circle.
const DIRECTIONS = array<vec2<f32>, 8>(
    vec2<f32>(1.0, 0.0), vec2<f32>(0.70710678, 0.70710678),
    vec2<f32>(0.0, 1.0), vec2<f32>(-0.70710678, 0.70710678),
    vec2<f32>(-1.0, 0.0), vec2<f32>(-0.70710678, -0.70710678),
    vec2<f32>(0.0, -1.0), vec2<f32>(0.70710678, -0.70710678),
);

fn log_depth(x: i32, y: i32) -> f32 {
    if x < 0 || y < 0 || x >= i32(frame.width) || y >= i32(frame.height) {
        return NO_DEPTH;
    }
    let d = pixel_depth(u32(y) * frame.width + u32(x));
    if d == EMPTY {
        return NO_DEPTH;
    }
    return log2(bitcast<f32>(d));
}

/// The shading factor (1 = unshaded) of a drawn pixel at `id` with depth bits `d`. Strength in
/// `frame.shading.x` (0: off), radius in pixels in `frame.shading.y`.
fn edl_factor(id: vec2<u32>, d: u32) -> f32 {
    // Without EDL the loop runs no tap and the factor is exp(0) = 1. Behind an early return
    // instead, lavapipe still paid for the eight taps: a third of the pyramid's shading pass.
    let taps = select(0, 8, frame.shading.x > 0.0);
    let ld = log2(bitcast<f32>(d));
    var response = 0.0;
    for (var k = 0; k < taps; k++) {
        let offset = round(DIRECTIONS[k] * frame.shading.y);
        let nd = log_depth(i32(id.x) + i32(offset.x), i32(id.y) + i32(offset.y));
        if nd != NO_DEPTH {
            response += max(0.0, ld - nd);
        }
    }
    return exp(-response / 8.0 * 300.0 * frame.shading.x);
}
