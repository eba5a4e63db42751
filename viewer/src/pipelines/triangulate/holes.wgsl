// The hole rate of the reconstruction: an empty pixel is a hole where covered pixels lie within
// HOLE_REACH on its left, its right, above and below it (inside the silhouette); the rate is
// holes over holes and covered pixels.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> reconstructed: array<u32>;
@group(0) @binding(2) var<storage, read_write> counts: array<atomic<u32>>;

const HOLE_REACH: i32 = 16;

fn covered(x: i32, y: i32) -> bool {
    if x < 0 || y < 0 || x >= i32(frame.width) || y >= i32(frame.height) {
        return false;
    }
    return reconstructed[u32(y) * frame.width + u32(x)] != EMPTY;
}

fn reaches(x: i32, y: i32, dx: i32, dy: i32) -> bool {
    for (var k = 1; k <= HOLE_REACH; k++) {
        if covered(x + k * dx, y + k * dy) {
            return true;
        }
    }
    return false;
}

var<workgroup> group_holes: atomic<u32>;
var<workgroup> group_covered: atomic<u32>;

// Summed per workgroup first: one global atomic per 256 pixels, not one per pixel.
@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let x = i32(id.x);
    let y = i32(id.y);
    if id.x < frame.width && id.y < frame.height {
        if covered(x, y) {
            atomicAdd(&group_covered, 1u);
        } else if reaches(x, y, -1, 0) && reaches(x, y, 1, 0) && reaches(x, y, 0, -1) && reaches(x, y, 0, 1) {
            atomicAdd(&group_holes, 1u);
        }
    }
    workgroupBarrier();
    if lane == 0u {
        atomicAdd(&counts[COUNT_HOLES], atomicLoad(&group_holes));
        atomicAdd(&counts[COUNT_COVERED], atomicLoad(&group_covered));
    }
}
