//! The GPU hidden-point removal against a direct CPU reading of paper 003, 3.1.2: per pixel,
//! the eight-cell ring on every level of the min-depth pyramid up to equation 1's level (level 0
//! for a background pixel where the points lie denser than DENSE_SPACING_PX), the most
//! occluding neighbour per sector, and the mean against the threshold. Both shapes of the
//! pass (`HprShape`: one pixel an invocation, or a 4x4 block with shared reads) are pinned to it.

use super::*;
use crate::gpu::{GpuContext, ProjectionPath};
use crate::pipelines::projection::FrameUniforms;
use bytemuck::Zeroable;

const EMPTY: u32 = u32::MAX;
const LABEL_POINT: u32 = 0;
const LABEL_HOLE: u32 = 1;
const LABEL_BACKGROUND: u32 = 2;

/// A point-pyramid cell: depth bits, packed pixel.
type Entry = (u32, u32);

/// A deterministic scene: a far wall with a fifth of its pixels empty, touching the left edge
/// (where a ring reaches outside the image) and with a margin of background elsewhere, and in
/// front of it a nearer tilted disc sampled at one pixel in four, so the wall shows between its
/// points. Linear depths as bits, EMPTY for background.
fn scene(w: u32, h: u32) -> Vec<u32> {
    let mut state = 0x2545_f491_u32;
    let mut random = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as f32 / u32::MAX as f32
    };
    let mut depths = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
            let mut d = EMPTY;
            if (0.0..0.94).contains(&u) && (0.08..0.9).contains(&v) && random() < 0.8 {
                d = (40.0 + 20.0 * u).to_bits();
            }
            let (du, dv) = (u - 0.45, v - 0.5);
            if du * du + dv * dv < 0.09 && random() < 0.25 {
                d = (8.0 + 6.0 * v).to_bits();
            }
            depths.push(d);
        }
    }
    depths
}

/// The labels of paper 003's operator (with the dense background rule), and per pixel the margin of its mean occlusion over the
/// threshold (where the GPU's single precision may decide either way).
fn reference(depths: &[u32], w: u32, h: u32, p: &PyramidUniforms) -> Vec<(u32, f64)> {
    // Level 0: every pixel's point, background at the far plane; then min-depth levels, ties
    // to the smaller packed pixel, as pyramid_down.wgsl.
    let mut levels: Vec<(u32, u32, Vec<Entry>)> = Vec::new();
    let base = (0..w * h)
        .map(|i| {
            let d = depths[i as usize];
            let d = if d == EMPTY { p.far.to_bits() } else { d };
            (d, (i % w) | ((i / w) << 16))
        })
        .collect();
    levels.push((w, h, base));
    while levels.len() < p.levels as usize {
        let (fw, fh, fine) = &levels[levels.len() - 1];
        let (cw, ch) = (fw.div_ceil(2), fh.div_ceil(2));
        let mut coarse = Vec::with_capacity((cw * ch) as usize);
        for y in 0..ch {
            for x in 0..cw {
                let mut best = (EMPTY, EMPTY);
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (fx, fy) = (2 * x + dx, 2 * y + dy);
                    if fx < *fw && fy < *fh {
                        best = best.min(fine[(fy * fw + fx) as usize]);
                    }
                }
                coarse.push(best);
            }
        }
        levels.push((cw, ch, coarse));
    }
    let point = |e: Entry| {
        let px = [(e.1 & 0xffff) as f64 + 0.5, (e.1 >> 16) as f64 + 0.5];
        let d = f32::from_bits(e.0) as f64;
        [
            (px[0] * p.pixel_scale[0] as f64 + p.pixel_bias[0] as f64) * d,
            (px[1] * p.pixel_scale[1] as f64 + p.pixel_bias[1] as f64) * d,
            -d,
        ]
    };
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    // Counter-clockwise from +x, as the shader's sectors.
    let ring = crate::pipelines::shader_tests::SECTOR_DIRECTIONS;
    let top = p.levels as i32 - 1;
    let c = p.coarse_level as usize;
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h as i32 {
        for x in 0..w as i32 {
            let (cw, _, cells) = &levels[c];
            let coarse = cells[((y >> c) * *cw as i32 + (x >> c)) as usize];
            let z = f32::from_bits(coarse.0).max(1e-6) as f64;
            let reach = ((p.hpr_scale as f64 / z).log2().round() as i32).clamp(1, top.max(1));
            let dense = (p.dense_scale as f64) < z;
            let background = if dense { 0 } else { reach };
            let d = depths[(y * w as i32 + x) as usize];
            let last = if d == EMPTY { background } else { reach };
            let me = point(levels[0].2[(y * w as i32 + x) as usize]);
            let mut sectors = [1.0f64; 8];
            for (l, (lw, lh, cells)) in levels.iter().enumerate().take(last as usize + 1) {
                let (lx, ly) = (x >> l, y >> l);
                for (s, (dx, dy)) in ring.iter().enumerate() {
                    let (nx, ny) = (lx + dx, ly + dy);
                    if nx < 0 || ny < 0 || nx >= *lw as i32 || ny >= *lh as i32 {
                        continue;
                    }
                    let other = point(cells[(ny * *lw as i32 + nx) as usize]);
                    let dir = [other[0] - me[0], other[1] - me[1], other[2] - me[2]];
                    let cos = dot(dir, other) / (dot(dir, dir) * dot(other, other)).sqrt();
                    sectors[s] = sectors[s].min(1.0 + cos);
                }
            }
            let mean = sectors.iter().sum::<f64>() / 8.0;
            let label = match (mean >= p.threshold as f64, d == EMPTY) {
                (false, _) => LABEL_HOLE,
                (true, true) => LABEL_BACKGROUND,
                (true, false) => LABEL_POINT,
            };
            out.push((label, (mean - p.threshold as f64).abs()));
        }
    }
    out
}

#[test]
fn hpr_labels_match_the_per_pixel_definition() {
    // Odd sizes: the last 4x4 blocks hang over the right and bottom edges.
    let (w, h) = (203u32, 151u32);
    let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
    let (device, queue) = (&ctx.device, &ctx.queue);
    let depths = scene(w, h);
    let buffer = |label: &str, contents: &[u8], usage: wgpu::BufferUsages| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage,
        })
    };
    let storage = wgpu::BufferUsages::STORAGE;
    let depth_buffer = buffer("depths", bytemuck::cast_slice(&depths), storage);
    let colours = buffer("colours", &vec![0xff; depths.len() * 4], storage);
    let uniforms = FrameUniforms {
        width: w,
        height: h,
        ..FrameUniforms::zeroed()
    };
    let uniforms = buffer(
        "frame",
        bytemuck::bytes_of(&uniforms),
        wgpu::BufferUsages::UNIFORM,
    );
    let output = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("output"),
        size: wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::STORAGE_BINDING,
        view_formats: &[],
    });
    let fov_y = 60f32.to_radians();
    let frame = PyramidFrame {
        // Equation 1 then asks for levels 3-4 on the disc and 1-2 on the wall; the wall's
        // spacing, 0.1 at depths 40-60, is under half a pixel: its background looks at level 0.
        s0: 0.1,
        fov_y,
        far: 100.0,
        focal_px: h as f32 * 0.5 / (fov_y * 0.5).tan(),
        light: [0.0; 4],
        stored_normals: false,
        view_rows: [[0.0; 4]; 3],
    };
    // Both shapes of the pass give the same labels, whichever this adapter would run.
    for shape in HprShape::ALL {
        let pyramid = PyramidPasses::new(device, shape).expect("pyramid passes");
        let targets = pyramid.targets(device, w, h);
        let inputs = PyramidInputs {
            frame_uniforms: &uniforms,
            depths: &depth_buffer,
            colours: &colours,
            output: &output,
        };
        let mut timer = Timer::new(device, queue, false, 32);
        timer.begin_frame(false);
        let mut encoder = device.create_command_encoder(&Default::default());
        pyramid.encode(
            device,
            queue,
            &mut encoder,
            &targets,
            &inputs,
            &frame,
            &mut timer,
        );
        queue.submit([encoder.finish()]);
        let bytes =
            read_buffer(&ctx, &targets.labels, (w * h * 4) as u64).expect("labels readback");
        let labels: &[u32] = bytemuck::cast_slice(&bytes);

        let expected = reference(&depths, w, h, &PyramidUniforms::new(&targets, &frame));
        let (mut wrong, mut on_threshold) = (Vec::new(), 0usize);
        for (i, (&got, &(want, margin))) in labels.iter().zip(&expected).enumerate() {
            // Single against double precision may only part where the mean sits on the threshold.
            if got != want && margin > 1e-4 {
                wrong.push((i as u32 % w, i as u32 / w, got, want));
            }
            on_threshold += usize::from(got != want && margin <= 1e-4);
        }
        assert!(
            on_threshold <= labels.len() / 1000,
            "{shape:?}: {on_threshold} labels differ from the reference at the threshold"
        );
        assert!(
            wrong.is_empty(),
            "{shape:?}: {} of {} labels differ from the reference (x, y, gpu, reference): {:?}",
            wrong.len(),
            labels.len(),
            &wrong[..wrong.len().min(12)]
        );
        // The scene asks for every outcome: wall points hidden behind the disc, open background
        // at the margin, background enclosed by the wall, and visible points on both surfaces.
        let count = |label: u32, depth: Option<f32>| {
            (0..depths.len())
                .filter(|&i| labels[i] == label)
                .filter(|&i| match depth {
                    Some(limit) => depths[i] != EMPTY && f32::from_bits(depths[i]) > limit,
                    None => true,
                })
                .count()
        };
        let hidden_wall = count(LABEL_HOLE, Some(30.0));
        let visible_disc = count(LABEL_POINT, None) - count(LABEL_POINT, Some(30.0));
        assert!(
            hidden_wall > 1000,
            "{shape:?}: {hidden_wall} wall points hidden"
        );
        assert!(
            visible_disc > 1000,
            "{shape:?}: {visible_disc} disc points visible"
        );
        assert!(count(LABEL_BACKGROUND, None) > 2000);
        assert!(count(LABEL_HOLE, None) > hidden_wall + 500);
    }
}
