// Normal estimation (section 3.4): the mean of the face normals of the point's fan, each turned
// towards the viewer, or, where `stored_normals`, the point's own normal (turned the same way)
// where it has one; and the search-radius feedback (section 3.6): each point tells each of
// its neighbours how far away it is, so that a neighbour learns the largest distance at which
// some point took it as its nearest (the paper's maximum blending).
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tri: Triangulate;
@group(0) @binding(2) var<storage, read> pts: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> neighbours: array<u32>;
// Per pixel: the unit normal in world space; 0 where the fan has no triangle.
@group(0) @binding(4) var<storage, read_write> normals: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> feedback: array<atomic<u32>>;
// Per pixel: the point's own normal as four snorm8, where the gather kept it; 0: none.
@group(0) @binding(6) var<storage, read> point_normals: array<u32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let p = id.y * frame.width + id.x;
    let me = pts[p];
    if me.w <= 0.0 {
        return;
    }
    let to_eye = tri.eye.xyz - me.xyz;
    // A dataset's normal, estimated from a point's k nearest neighbours in the world (or
    // measured), is steadier than one from the eight sector neighbours a pixel apart: scan noise
    // and a mesh's facets tilt each fan's triangles (the bunny's and Spot's shading banded along
    // the facets, where the reference shades the mesh smoothly). Where it is taken, the fan
    // still runs for the feedback, but sums no face normals.
    var own = 0u;
    if tri.stored_normals != 0u {
        own = point_normals[p];
    }
    var sum = vec3<f32>(0.0);
    var first = 0u;
    var previous = 0u;
    var previous_q = vec3<f32>(0.0);
    for (var s = 0u; s <= SECTORS; s++) {
        let word = fan_step(p, s, first, previous);
        if word == 0u {
            continue;
        }
        let q = pts[~word].xyz;
        if s < SECTORS {
            atomicMax(&feedback[~word], bitcast<u32>(distance(me.xyz, q)));
        }
        if own == 0u && previous != 0u && opens(p, ~previous, ~word) {
            let n = cross(previous_q - me.xyz, q - me.xyz);
            let len = length(n);
            if len > 0.0 {
                sum += select(n, -n, dot(n, to_eye) < 0.0) / len;
            }
        }
        if first == 0u {
            first = word;
        }
        previous = word;
        previous_q = q;
    }
    if own != 0u {
        let n = normalize(unpack4x8snorm(own).xyz);
        normals[p] = vec4<f32>(select(n, -n, dot(n, to_eye) < 0.0), 1.0);
        return;
    }
    let len = length(sum);
    if len > 0.0 {
        normals[p] = vec4<f32>(sum / len, 1.0);
    } else {
        // No triangle: the raster lends the triangles this point is a corner of their own
        // normal, and the shade lights a pixel that only such points drew.
        normals[p] = vec4<f32>(0.0);
    }
}
