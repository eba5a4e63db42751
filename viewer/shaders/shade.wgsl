// Final pass into the output image: the resolved colour, with eye-dome lighting when
// edl_strength > 0 (the log-depth differences to eight neighbours darken depth edges).
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> depths: array<u32>;
@group(0) @binding(2) var<storage, read> colours: array<u32>;
@group(0) @binding(3) var output: texture_storage_2d<rgba8unorm, write>;

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
    let d = depths[u32(y) * frame.width + u32(x)];
    if d == EMPTY {
        return NO_DEPTH;
    }
    return log2(bitcast<f32>(d));
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    if depths[i] == EMPTY {
        textureStore(output, vec2<i32>(id.xy), unpack4x8unorm(frame.background));
        return;
    }
    var c = unpack4x8unorm(colours[i]);
    if frame.edl_strength > 0.0 {
        let ld = log2(bitcast<f32>(depths[i]));
        let r = frame.edl_radius;
        var response = 0.0;
        for (var k = 0; k < 8; k++) {
            let offset = round(DIRECTIONS[k] * r);
            let nx = i32(id.x) + i32(offset.x);
            let ny = i32(id.y) + i32(offset.y);
            let nd = log_depth(nx, ny);
            if nd != NO_DEPTH {
                response += max(0.0, ld - nd);
            }
        }
        let shade = exp(-response / 8.0 * 300.0 * frame.edl_strength);
        c = vec4<f32>(c.rgb * shade, 1.0);
    }
    textureStore(output, vec2<i32>(id.xy), vec4<f32>(c.rgb, 1.0));
}
