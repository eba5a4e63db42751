// The depth noise of the frame's visible points, for the normal estimation: a normal taken
// over cells of 2^l pixels averages 4^l noisy depths, so noise that the point spacing alone
// does not show needs coarser levels. `histogram` bins, for every visible point between two
// visible neighbours (along x, and along y), the residual of its depth against their mean,
// in log steps of s0; `estimate` takes the median, robust to the silhouettes and creases
// that also leave residuals, and turns it into the level scale the shading uses.
// The residual is taken on inverse depth, which is linear across the pixels of a plane in
// perspective: slanted planes leave none, so grazing views do not read as noise.

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

// NOISE_BINS counts, then as f32 bits the noise scale (copied into `pyr.noise_scale`) and the
// deviation in dataset units (read back for the statistics).
@group(1) @binding(9) var<storage, read_write> noise: array<atomic<u32>>;
// Counted per workgroup first: one global add per bin and workgroup, not one per residual.
var<workgroup> local_bins: array<atomic<u32>, NOISE_BINS>;

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
}

@compute @workgroup_size(16, 16)
fn histogram(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    if lane < NOISE_BINS {
        atomicStore(&local_bins[lane], 0u);
    }
    workgroupBarrier();
    add_pixel(id.xy);
    workgroupBarrier();
    if lane < NOISE_BINS {
        let n = atomicLoad(&local_bins[lane]);
        if n > 0u {
            atomicAdd(&noise[lane], n);
        }
    }
}

// One invocation: the median bin, as the noise scale. The shading's noise level at depth z is
// 0.5 log2(noise_scale / z), from sqrt(2) sigma / (4^l z pixel) <= tolerance. Where points
// are sparser than pixels a cell averages fewer depths, but the normal radius of the spacing
// (NORMAL_SCALE_S0) already covers that: counting them as well measured 0.9 dB worse at 0.1
// points per pixel.
@compute @workgroup_size(1)
fn estimate() {
    var total = 0u;
    for (var b = 0u; b < NOISE_BINS; b++) {
        total += atomicLoad(&noise[b]);
    }
    var sigma = 0.0;
    if total >= MIN_RESIDUALS {
        var seen = 0u;
        var b = 0u;
        for (; b < NOISE_BINS; b++) {
            seen += atomicLoad(&noise[b]);
            if 2u * seen >= total {
                break;
            }
        }
        // Bin 0 also holds the exact zeros of clean data: no noise.
        if b > 0u {
            let median = exp2((f32(b) + 0.5 - ZERO_BIN) / BINS_PER_OCTAVE) * pyr.s0;
            sigma = MEDIAN_TO_SIGMA * median;
        }
    }
    let pixel = abs(pyr.pixel_scale.y);
    let scale = 1.4142135 * sigma / (pixel * NOISE_SLOPE_TOLERANCE);
    atomicStore(&noise[NOISE_BINS], bitcast<u32>(scale));
    atomicStore(&noise[NOISE_BINS + 1u], bitcast<u32>(sigma));
}
