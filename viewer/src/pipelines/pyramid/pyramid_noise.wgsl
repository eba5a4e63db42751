// The depth noise of the frame's visible points, for the normal estimation: a normal taken
// over cells of 2^l pixels averages 4^l noisy depths, so noise that the point spacing alone
// does not show needs coarser levels. `histogram` bins, for every visible point between two
// visible neighbours (along x, and along y), the residual of its depth against their mean,
// in log steps of s0; `estimate` takes the median, robust to the silhouettes and creases
// that also leave residuals, and turns it into the level scale the shading uses.
// The residual is taken on inverse depth, which is linear across the pixels of a plane in
// perspective: slanted planes leave none, so grazing views do not read as noise.
// With `stored_normals` the dataset's normals are measured alike, for how many of them the
// shading averages: the angle between each visible point's normal and the mean of its two
// neighbours' (a normal turning steadily across a curved surface leaves none), its median
// giving their noise. Normals sampled from a mesh have none; normals a converter estimated
// from a noisy scan do.

// Quarter octaves of |residual| / s0 from 2^-12 (bin 0, also exact zeros) to 2^8.
const NOISE_BINS: u32 = 80u;
const BINS_PER_OCTAVE: f32 = 4.0;
const ZERO_BIN: f32 = 48.0;
// Fewer residuals than this and the estimate is left at no noise.
const MIN_RESIDUALS: u32 = 256u;
// The median |residual| of Gaussian depth noise sigma is 0.826 sigma (the residual against
// the mean of two neighbours has deviation sigma * sqrt(1.5)).
const MEDIAN_TO_SIGMA: f32 = 1.211;
// The normal error, as a slope, that noise may cause: a normal over cells of 2^l pixels of
// footprint f, each the mean of 4^l depths, has a slope error of sqrt(2) sigma / (4^l f).
// About 3 degrees: measured with the quality harness against 1 and 4 degrees, it gives the
// best SSIM on the real bunny scans (22.2 dB / 0.823, against 21.9 / 0.817 and 22.2 / 0.821),
// with the noisy sampled meshes between the two.
const NOISE_SLOPE_TOLERANCE: f32 = 0.05;
// The same for the stored normals: their mean over cells of 2^l pixels (4^l normals) has an
// angular error of sigma / 2^l (sigma the deviation of each of a normal's two tangent
// components). About 1.7 degrees: measured with the quality harness against 0.05 (3 degrees),
// it gives the real bunny scans' pyramid the lower normal error and the better SSIM (4.3
// against 5.7 degrees, 0.870 against 0.826; PSNR 21.5 against 22.4 dB); normals sampled from
// a mesh stay at level 0 under either.
const NORMAL_ANGLE_TOLERANCE: f32 = 0.03;
// The angle between a normal and the mean of its two neighbours' is the length of a 2-D
// Gaussian of deviation sqrt(1.5) sigma a component: Rayleigh, of median sqrt(2 ln 2) sqrt(1.5)
// sigma = 1.442 sigma.
const ANGLE_MEDIAN_TO_SIGMA: f32 = 0.6935;

// NOISE_BINS counts, then as f32 bits the noise scale (copied into `pyr.noise_scale`) and the
// deviation in dataset units (read back for the statistics); then NOISE_BINS counts of the
// stored normals' angles, and as f32 bits the level the shading averages them at (copied into
// `pyr.stored_level`).
@group(1) @binding(9) var<storage, read_write> noise: array<atomic<u32>>;
// Counted per workgroup first: one global add per bin and workgroup, not one per residual.
// The stored normals' angles from NOISE_BINS on.
var<workgroup> local_bins: array<atomic<u32>, 2 * NOISE_BINS>;

const ANGLE_BINS_AT: u32 = NOISE_BINS + 2u;
const STORED_LEVEL_AT: u32 = 2u * NOISE_BINS + 2u;

fn visible_depth(p: vec2<i32>) -> f32 {
    let i = u32(p.y) * frame.width + u32(p.x);
    return select(0.0, bitcast<f32>(depths[i]), labels[i] == LABEL_POINT);
}

fn add_residual(d: f32, a: f32, b: f32) {
    if a <= 0.0 || b <= 0.0 {
        return;
    }
    let r = abs(1.0 / d - 0.5 * (1.0 / a + 1.0 / b)) * d * d / pyr.s0;
    let bin = clamp(floor(log2(r) * BINS_PER_OCTAVE) + ZERO_BIN, 0.0, f32(NOISE_BINS - 1u));
    atomicAdd(&local_bins[u32(bin)], 1u);
}

// The stored normal at visible point `p`; none (zero) elsewhere.
fn visible_normal(p: vec2<i32>) -> vec3<f32> {
    let i = u32(p.y) * frame.width + u32(p.x);
    if labels[i] != LABEL_POINT || normals[i] == NO_NORMAL {
        return vec3<f32>(0.0);
    }
    return decode_normal(normals[i]);
}

fn add_angle(n: vec3<f32>, a: vec3<f32>, b: vec3<f32>) {
    let mean = a + b;
    if dot(a, a) == 0.0 || dot(b, b) == 0.0 || dot(mean, mean) < 1e-6 {
        return;
    }
    let angle = acos(clamp(dot(n, normalize(mean)), -1.0, 1.0));
    let bin = clamp(floor(log2(angle) * BINS_PER_OCTAVE) + ZERO_BIN, 0.0, f32(NOISE_BINS - 1u));
    atomicAdd(&local_bins[NOISE_BINS + u32(bin)], 1u);
}

fn add_pixel(id: vec2<u32>) {
    if id.x == 0u || id.y == 0u || id.x + 1u >= frame.width || id.y + 1u >= frame.height {
        return;
    }
    let p = vec2<i32>(id);
    let d = visible_depth(p);
    if d <= 0.0 {
        return;
    }
    add_residual(d, visible_depth(p - vec2<i32>(1, 0)), visible_depth(p + vec2<i32>(1, 0)));
    add_residual(d, visible_depth(p - vec2<i32>(0, 1)), visible_depth(p + vec2<i32>(0, 1)));
    if pyr.stored_normals != 0u {
        let n = visible_normal(p);
        if dot(n, n) > 0.0 {
            add_angle(n, visible_normal(p - vec2<i32>(1, 0)), visible_normal(p + vec2<i32>(1, 0)));
            add_angle(n, visible_normal(p - vec2<i32>(0, 1)), visible_normal(p + vec2<i32>(0, 1)));
        }
    }
}

@compute @workgroup_size(16, 16)
fn histogram(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    if lane < 2u * NOISE_BINS {
        atomicStore(&local_bins[lane], 0u);
    }
    workgroupBarrier();
    add_pixel(id.xy);
    workgroupBarrier();
    if lane < 2u * NOISE_BINS {
        let n = atomicLoad(&local_bins[lane]);
        if n > 0u {
            atomicAdd(&noise[lane + select(0u, 2u, lane >= NOISE_BINS)], n);
        }
    }
}

// The median bin of the NOISE_BINS counts from `first`, as the value it stands for (bin 0,
// which also holds exact zeros, and too few counts: 0).
fn median_of(first: u32) -> f32 {
    var total = 0u;
    for (var b = 0u; b < NOISE_BINS; b++) {
        total += atomicLoad(&noise[first + b]);
    }
    if total < MIN_RESIDUALS {
        return 0.0;
    }
    var seen = 0u;
    var b = 0u;
    for (; b < NOISE_BINS; b++) {
        seen += atomicLoad(&noise[first + b]);
        if 2u * seen >= total {
            break;
        }
    }
    if b == 0u {
        return 0.0;
    }
    return exp2((f32(b) + 0.5 - ZERO_BIN) / BINS_PER_OCTAVE);
}

// One invocation: the median bin, as the noise scale. The shading's noise level at depth z is
// 0.5 log2(noise_scale / z), from sqrt(2) sigma / (4^l z pixel) <= tolerance. Where points
// are sparser than pixels a cell averages fewer depths, but the normal radius of the spacing
// (NORMAL_SCALE_S0) already covers that: counting them as well measured 0.9 dB worse at 0.1
// points per pixel.
@compute @workgroup_size(1)
fn estimate() {
    let sigma = MEDIAN_TO_SIGMA * median_of(0u) * pyr.s0;
    let pixel = abs(pyr.pixel_scale.y);
    let scale = 1.4142135 * sigma / (pixel * NOISE_SLOPE_TOLERANCE);
    atomicStore(&noise[NOISE_BINS], bitcast<u32>(scale));
    atomicStore(&noise[NOISE_BINS + 1u], bitcast<u32>(sigma));
    let angle = ANGLE_MEDIAN_TO_SIGMA * median_of(ANGLE_BINS_AT);
    let level = select(0.0, log2(angle / NORMAL_ANGLE_TOLERANCE), angle > NORMAL_ANGLE_TOLERANCE);
    atomicStore(&noise[STORED_LEVEL_AT], bitcast<u32>(level));
}
