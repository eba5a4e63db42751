// Normalisation and shading: colour and normal are the sums over the fragments divided by
// their weight, lit by the shared headlight; the depth is the least. The reconstructed depth
// plane is what the next frame reprojects; the surface and the albedo are kept for the harness.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tri: Triangulate;
// Binding 2, the blend sums: shade_sums32.wgsl or shade_sums64.wgsl, with blend_at.
@group(0) @binding(3) var<storage, read> front: array<u32>;
// Linear depth bits per pixel, EMPTY on background.
@group(0) @binding(4) var<storage, read_write> reconstructed: array<u32>;
// View-space normal (x right, y up, z towards the eye) and linear depth; w < 0: background.
@group(0) @binding(5) var<storage, read_write> surface: array<vec4<f32>>;
// Unlit colour, alpha 0 on background.
@group(0) @binding(6) var<storage, read_write> albedo: array<u32>;
@group(0) @binding(7) var output: texture_storage_2d<rgba8unorm, write>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let p = id.y * frame.width + id.x;
    let blend = blend_at(p);
    if blend.fragments == 0u || front[p] == 0u {
        reconstructed[p] = EMPTY;
        surface[p] = vec4<f32>(0.0, 0.0, 0.0, -1.0);
        albedo[p] = 0u;
        textureStore(output, id.xy, unpack4x8unorm(frame.background));
        return;
    }
    let rgb = blend.colour;
    let blended = blend.normal * 2.0 - 1.0;
    let depth = bitcast<f32>(~front[p]);
    let nx = (f32(id.x) + 0.5) / f32(frame.width) * 2.0 - 1.0;
    let ny = 1.0 - (f32(id.y) + 0.5) / f32(frame.height) * 2.0;
    let to_eye = -normalize(tri.forward.xyz + nx * tri.right.xyz + ny * tri.up.xyz);
    var n = to_eye;
    if dot(blended, blended) > 1e-8 {
        n = normalize(blended);
    }
    let colour = headlight(rgb, n, to_eye);
    let right = normalize(tri.right.xyz);
    let up = normalize(tri.up.xyz);
    reconstructed[p] = bitcast<u32>(depth);
    surface[p] = vec4<f32>(dot(n, right), dot(n, up), -dot(n, normalize(tri.forward.xyz)), depth);
    albedo[p] = pack4x8unorm(vec4<f32>(rgb, 1.0));
    textureStore(output, id.xy, vec4<f32>(clamp(colour, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0));
}
