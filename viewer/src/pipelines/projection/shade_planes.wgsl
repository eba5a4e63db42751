// The separate-pass shading of the resolved planes into the output image: background where no
// point landed, else the pipeline's `shade_pixel` of the resolved colour.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> depths: array<u32>;
@group(0) @binding(2) var<storage, read> colours: array<u32>;
@group(0) @binding(3) var output: texture_storage_2d<rgba8unorm, write>;

fn pixel_depth(i: u32) -> u32 {
    return depths[i];
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let d = depths[i];
    if d == EMPTY {
        textureStore(output, vec2<i32>(id.xy), unpack4x8unorm(frame.background));
        return;
    }
    let c = shade_pixel(id.xy, d, unpack4x8unorm(colours[i]).rgb);
    textureStore(output, vec2<i32>(id.xy), vec4<f32>(c, 1.0));
}
