// The neighbour search (section 3.3): each point P covers the pixels of its search sphere
// projected to the screen (at most `max_search_px` either side), and for each point Q there that lies within that radius in world
// space, offers itself as Q's neighbour in the sector of Q in which P lies. The variant
// appended before this file defines `visit`: the distance pass keeps the least distance per
// sector, the id pass registers the point at that distance. Beyond the paper, where the normals
// tell a surface's sides apart (SIDES; `point_normals`, kept by the gather), two points on
// opposite sides are not neighbours: a sheet thinner than the point spacing, sampled on both
// faces, keeps both faces' points at one pixel each, and fans across them zigzag between the
// faces.

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let p = id.y * frame.width + id.x;
    var me = pts[p];
    if me.w == 0.0 {
        return;
    }
    // A culled point (w < 0) offers itself to the points round it; it takes none (search
    // skips it below as a receiver).
    me.w = abs(me.w);
    // The screen box of the search sphere, exact (its tangent planes through the eye): off the
    // axis a sphere projects larger than r f / d; one reaching behind the eye takes the largest.
    let rel = me.xyz - tri.eye.xyz;
    let z = dot(rel, tri.forward.xyz);
    let tan_x = length(tri.right.xyz);
    let tan_y = length(tri.up.xyz);
    let sx = tangent_slopes(dot(rel, tri.right.xyz) / tan_x, z, me.w);
    let sy = tangent_slopes(dot(rel, tri.up.xyz) / tan_y, z, me.w);
    let behind = z <= me.w || sx.x > sx.y || sy.x > sy.y;
    let lo = vec2<f32>((sx.x / tan_x * 0.5 + 0.5) * f32(frame.width), (0.5 - sy.y / tan_y * 0.5) * f32(frame.height));
    let hi = vec2<f32>((sx.y / tan_x * 0.5 + 0.5) * f32(frame.width), (0.5 - sy.x / tan_y * 0.5) * f32(frame.height));
    var mine = 0u;
    if SIDES {
        mine = point_normals[p];
    }
    let my_normal = unpack4x8snorm(mine).xyz;
    let most = i32(tri.max_search_px);
    var x0 = -most;
    var x1 = most;
    var y0 = -most;
    var y1 = most;
    if !behind {
        x0 = max(i32(floor(lo.x)) - i32(id.x), -most);
        x1 = min(i32(floor(hi.x)) - i32(id.x), most);
        y0 = max(i32(floor(lo.y)) - i32(id.y), -most);
        y1 = min(i32(floor(hi.y)) - i32(id.y), most);
    }
    for (var dy = y0; dy <= y1; dy++) {
        let y = i32(id.y) + dy;
        if y < 0 || y >= i32(frame.height) {
            continue;
        }
        for (var dx = x0; dx <= x1; dx++) {
            let x = i32(id.x) + dx;
            if x < 0 || x >= i32(frame.width) || (dx == 0 && dy == 0) {
                continue;
            }
            let q = u32(y) * frame.width + u32(x);
            let other = pts[q];
            if other.w <= 0.0 {
                continue;
            }
            let dist = distance(me.xyz, other.xyz);
            if dist > me.w || (SIDES && mine != 0u && !same_side(my_normal, point_normals[q])) {
                continue;
            }
            // P lies at (-dx, -dy) from Q.
            visit(q * SECTORS + sector_of(f32(-dx), f32(-dy)), bitcast<u32>(dist), p);
        }
    }
}

// Normals more than 120 degrees apart lie on a surface's two sides (a sheet's faces lie 180
// apart); a normal leaning 45 to 55 degrees off its face near an edge (cull.wgsl) stays within.
const OPPOSITE_SIDES: f32 = -0.5;

// Whether a point with normal `my_normal` and one with the word `theirs` (gather.wgsl) may
// connect: on the same side, or the other without a normal (0).
fn same_side(my_normal: vec3<f32>, theirs: u32) -> bool {
    return theirs == 0u || dot(my_normal, unpack4x8snorm(theirs).xyz) >= OPPOSITE_SIDES;
}

// The tangents through the eye of a sphere of radius r whose centre lies `a` off the axis at
// depth z, as slopes a / z (least, greatest); least > greatest where a tangent lies at or
// beyond 90 degrees from the axis.
fn tangent_slopes(a: f32, z: f32, r: f32) -> vec2<f32> {
    let t = sqrt(max(a * a + z * z - r * r, 0.0));
    let near = z * t + a * r;
    let far = z * t - a * r;
    if near <= 0.0 || far <= 0.0 {
        return vec2<f32>(1.0, -1.0);
    }
    return vec2<f32>((a * t - z * r) / near, (a * t + z * r) / far);
}
