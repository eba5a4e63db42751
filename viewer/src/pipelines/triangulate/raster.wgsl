// Triangulation (section 3.5): each point rasterizes the triangles of its fan, interpolating
// colour, normal and linear depth over the pixels whose centres they cover; colour and normal
// are summed (the paper's additive blending, normalised when shading) and the depth kept by
// minimum. As in the paper no fragment is depth tested: what lies behind the front surface is
// kept out by culling its points against the previous frame's depth (gather.wgsl), so for the
// frames after a jump or a disocclusion the colours behind show through until the depth is
// there. A compute rasterizer: fixed-point atomic sums make the picture independent of the
// order triangles arrive in (on the 64-bit sums, for a pixel's first 512 fragments), and it
// runs on every adapter the projection runs on. A triangle in the fans of two or three of its
// corners is drawn each time, as in the paper: finding the one fan to draw it from (reading the
// other corners' fans) took longer on lavapipe than the repeated drawing. Each point also covers its own pixel, so that a point without neighbours
// is still drawn (adding no normal where its fan has none: see shade.wgsl).
// Where the normals tell a surface's sides apart (SIDES), the fans of the points whose normal
// faces away from the eye add to sums of their own, which the shade takes only where the
// front faces' left a pixel empty: a closed surface's far side and a thin sheet's back face
// fill the front's gaps without mixing their colours into it (a sign painted on one side,
// Spot's texture showing through its own body where the cull left a point behind).
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> pts: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> neighbours: array<u32>;
@group(0) @binding(3) var<storage, read> normals: array<vec4<f32>>;
// The projection's resolved colour per pixel (RGBA8).
@group(0) @binding(4) var<storage, read> colours: array<u32>;
// Bindings 5 and 9, the blend sums of the front and the back faces: raster_sums32.wgsl or
// raster_sums64.wgsl, with add_sums.
// Per pixel: the complement of the least depth's bits (0: nothing drawn).
@group(0) @binding(6) var<storage, read_write> front: array<atomic<u32>>;
@group(0) @binding(7) var<storage, read_write> counts: array<atomic<u32>>;
@group(0) @binding(8) var<uniform> tri: Triangulate;
// Per pixel: the point's own normal as four snorm8 (gather.wgsl); 0: none.
@group(0) @binding(10) var<storage, read> point_normals: array<u32>;

// Where SIDES: the fan drawn faces away from the eye (its point's own normal does).
var<private> back_face: bool;

struct Vertex {
    // Screen position in pixels (y down) and 1 / linear depth.
    xy: vec2<f32>,
    inv_w: f32,
    colour: vec3<f32>,
    // The fan's normal; 0 where the point's fan has no triangle.
    normal: vec3<f32>,
    pos: vec3<f32>,
}

fn vertex(q: u32) -> Vertex {
    var v: Vertex;
    let clip = frame.view_proj * vec4<f32>(pts[q].xyz, 1.0);
    let w = max(clip.w, 1e-6);
    v.xy = vec2<f32>((clip.x / w * 0.5 + 0.5) * f32(frame.width), (0.5 - clip.y / w * 0.5) * f32(frame.height));
    v.inv_w = 1.0 / w;
    v.colour = unpack4x8unorm(colours[q]).rgb;
    v.normal = normals[q].xyz;
    v.pos = pts[q].xyz;
    return v;
}

fn add_fragment(pixel: u32, depth: f32, colour: vec3<f32>, normal: vec3<f32>) {
    atomicMax(&front[pixel], ~bitcast<u32>(depth));
    let zero = vec3<f32>(0.0);
    let one = vec3<f32>(1.0);
    add_sums(pixel, clamp(colour, zero, one), clamp(normal * 0.5 + 0.5, zero, one), back_face);
}

fn edge(a: vec2<f32>, b: vec2<f32>, c: vec2<f32>) -> f32 {
    return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

fn rasterize(a: Vertex, b: Vertex, c: Vertex) {
    let area = edge(a.xy, b.xy, c.xy);
    if abs(area) < 1e-12 {
        return;
    }
    let lo = floor(min(a.xy, min(b.xy, c.xy)));
    let hi = ceil(max(a.xy, max(b.xy, c.xy)));
    if any(hi - lo > vec2<f32>(MAX_TRIANGLE_PX)) {
        return;
    }
    let x0 = u32(max(lo.x, 0.0));
    let y0 = u32(max(lo.y, 0.0));
    let x1 = u32(clamp(hi.x, 0.0, f32(frame.width)));
    let y1 = u32(clamp(hi.y, 0.0, f32(frame.height)));
    if x1 <= x0 || y1 <= y0 {
        return;
    }
    let inv_area = 1.0 / area;
    // A corner whose own fan has no triangle (a point at a silhouette, or with one neighbour)
    // takes this triangle's normal, turned towards the eye: the eye's direction would light it
    // as if it faced the viewer, a bright speck along the outline.
    var na = a.normal;
    var nb = b.normal;
    var nc = c.normal;
    if any(vec3<bool>(dot(na, na) == 0.0, dot(nb, nb) == 0.0, dot(nc, nc) == 0.0)) {
        var face = cross(b.pos - a.pos, c.pos - a.pos);
        let len = length(face);
        if len > 0.0 {
            face = select(face, -face, dot(face, tri.eye.xyz - a.pos) < 0.0) / len;
        }
        na = select(na, face, dot(na, na) == 0.0);
        nb = select(nb, face, dot(nb, nb) == 0.0);
        nc = select(nc, face, dot(nc, nc) == 0.0);
    }
    let pixel_box = vec4<u32>(x0, y0, x1 - 1u, y1 - 1u);
    let pixels = box_pixels(pixel_box);
    var next = pixel_box.xy;
    for (var k = 0u; k < pixels; k++) {
        let x = next.x;
        let y = next.y;
        next = box_next(pixel_box, next);
        let centre = vec2<f32>(f32(x) + 0.5, f32(y) + 0.5);
        // Barycentric weights, positive inside whichever way the triangle winds.
        let wa = edge(b.xy, c.xy, centre) * inv_area;
        let wb = edge(c.xy, a.xy, centre) * inv_area;
        let wc = 1.0 - wa - wb;
        if wa < 0.0 || wb < 0.0 || wc < 0.0 {
            continue;
        }
        // Perspective-correct: the weights over depth, normalised.
        let pa = wa * a.inv_w;
        let pb = wb * b.inv_w;
        let pc = wc * c.inv_w;
        let depth = 1.0 / (pa + pb + pc);
        let colour = (pa * a.colour + pb * b.colour + pc * c.colour) * depth;
        let normal = (pa * na + pb * nb + pc * nc) * depth;
        add_fragment(y * frame.width + x, depth, colour, normal);
    }
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let p = id.y * frame.width + id.x;
    if pts[p].w <= 0.0 {
        return;
    }
    let centre = vertex(p);
    back_face = false;
    if SIDES {
        // A point without a normal of its own counts as facing the eye.
        let own = point_normals[p];
        back_face = own != 0u && dot(unpack4x8snorm(own).xyz, tri.eye.xyz - centre.pos) < 0.0;
    }
    add_fragment(p, 1.0 / centre.inv_w, centre.colour, centre.normal);
    var drawn = 0u;
    var first = 0u;
    var previous = 0u;
    var previous_v: Vertex;
    for (var s = 0u; s <= SECTORS; s++) {
        let word = fan_step(p, s, first, previous);
        if word == 0u {
            continue;
        }
        let v = vertex(~word);
        if previous != 0u && opens(p, ~previous, ~word) {
            rasterize(centre, previous_v, v);
            drawn += 1u;
        }
        if first == 0u {
            first = word;
        }
        previous = word;
        previous_v = v;
    }
    if drawn > 0u {
        atomicAdd(&counts[COUNT_TRIANGLES], drawn);
    }
}
