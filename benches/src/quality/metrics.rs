//! How close a rendered frame is to the reference: PSNR and SSIM of the shaded image over the
//! object, depth and normal error, and the rates of holes and leaks.

use glam::Vec3;

/// A frame to judge: its image and, per pixel, the surface it shows.
pub struct Frame<'a> {
    pub width: u32,
    pub height: u32,
    pub rgba: &'a [u8],
    /// Per pixel: linear depth and, where the pipeline has one, the view-space normal.
    pub surface: Vec<Option<(f32, Option<Vec3>)>>,
}

#[derive(Debug, Clone, Copy, Default)]
pub struct Metrics {
    /// Over the pixels where either image shows the object, in dB (capped at 100).
    pub psnr: f64,
    /// Mean SSIM (11x11 Gaussian windows, luminance) over the same pixels.
    pub ssim: f64,
    /// Mean |depth - reference depth| / reference depth where both show a surface.
    pub depth_err: f64,
    /// Mean angle to the reference normal in degrees where both show a surface.
    pub normal_err_deg: f64,
    /// Reference surface pixels the frame leaves empty, over all reference surface pixels.
    pub hole_rate: f64,
    /// Pixels showing a surface behind the reference one, or surface where the reference
    /// shows background, over all reference surface pixels.
    pub leak_rate: f64,
    /// Mean distance in pixels between the frame's outline and the reference's.
    pub silhouette_px: f64,
}

/// A frame's surface is "behind" the reference where its depth exceeds it by this fraction.
pub const LEAK_DEPTH_TOLERANCE: f32 = 0.02;

/// `tan_half` is tan of half the horizontal and vertical field of view, for the normals of
/// frames that have none (estimated from their depth, the same way for every pipeline).
pub fn compare(
    reference_rgba: &[u8],
    reference: &[Option<([f32; 3], f32)>],
    frame: &Frame,
    tan_half: [f32; 2],
) -> Metrics {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let n = w * h;
    let ref_fg: Vec<bool> = reference.iter().map(Option::is_some).collect();
    let test_fg: Vec<bool> = frame.surface.iter().map(Option::is_some).collect();
    let region: Vec<bool> = (0..n).map(|i| ref_fg[i] || test_fg[i]).collect();
    let ref_count = ref_fg.iter().filter(|b| **b).count();

    let (psnr, ssim) = colour_scores(reference_rgba, frame.rgba, &region, w, h);

    let normals = normals_of(frame, tan_half);
    let mut depth_err = Vec::new();
    let mut normal_err = Vec::new();
    let mut holes = 0usize;
    let mut leaks = 0usize;
    for i in 0..n {
        match (&reference[i], &frame.surface[i]) {
            (Some((rn, rd)), Some((td, _))) => {
                depth_err.push(((td - rd).abs() / rd) as f64);
                if *td > rd * (1.0 + LEAK_DEPTH_TOLERANCE) {
                    leaks += 1;
                }
                if let Some(tn) = normals[i] {
                    let cos = Vec3::from_array(*rn).dot(tn).abs().min(1.0);
                    normal_err.push((cos.acos() as f64).to_degrees());
                }
            }
            (Some(_), None) => holes += 1,
            (None, Some(_)) => leaks += 1,
            (None, None) => {}
        }
    }
    let rate = |k: usize| k as f64 / ref_count.max(1) as f64;
    Metrics {
        psnr,
        ssim,
        depth_err: mean(depth_err.into_iter()),
        normal_err_deg: mean(normal_err.into_iter()),
        hole_rate: rate(holes),
        leak_rate: rate(leaks),
        silhouette_px: super::silhouette::silhouette_error(&ref_fg, &test_fg, w, h),
    }
}

/// PSNR and SSIM of a frame's unlit colour against the reference's albedo, over the pixels
/// where either shows the object: the one comparison of colour that is fair between pipelines
/// that light differently.
pub fn albedo_scores(
    reference_albedo: &[u8],
    reference: &[Option<([f32; 3], f32)>],
    frame: &Frame,
    albedo: &[u8],
) -> (f64, f64) {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let region: Vec<bool> = reference
        .iter()
        .zip(&frame.surface)
        .map(|(r, f)| r.is_some() || f.is_some())
        .collect();
    colour_scores(reference_albedo, albedo, &region, w, h)
}

/// PSNR (dB, capped at 100) and mean SSIM (11x11 Gaussian windows, luminance) of `rgba` against
/// `reference` over the pixels of `region`.
pub fn colour_scores(
    reference: &[u8],
    rgba: &[u8],
    region: &[bool],
    w: usize,
    h: usize,
) -> (f64, f64) {
    let n = w * h;
    let mut se = 0.0f64;
    let mut region_count = 0usize;
    for i in (0..n).filter(|&i| region[i]) {
        for c in 0..3 {
            let d = (reference[4 * i + c] as f64 - rgba[4 * i + c] as f64) / 255.0;
            se += d * d;
        }
        region_count += 1;
    }
    let mse = se / (3 * region_count.max(1)) as f64;
    let psnr = if mse <= 1e-10 {
        100.0
    } else {
        (10.0 * (1.0 / mse).log10()).min(100.0)
    };
    let luma = |rgba: &[u8]| -> Vec<f64> {
        rgba.chunks_exact(4)
            .map(|p| (0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64) / 255.0)
            .collect()
    };
    let ssim_map = ssim(&luma(reference), &luma(rgba), w, h);
    let ssim = mean((0..n).filter(|&i| region[i]).map(|i| ssim_map[i]));
    (psnr, ssim)
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, count) = values.fold((0.0, 0usize), |(s, c), v| (s + v, c + 1));
    if count == 0 { 0.0 } else { sum / count as f64 }
}

/// Per-pixel SSIM (Wang, Bovik, Sheikh and Simoncelli 2004): statistics over an 11x11 Gaussian
/// window of deviation 1.5 pixels, clipped at the borders (its weights there renormalised),
/// with K1 = 0.01, K2 = 0.03 and a dynamic range of 1.
pub fn ssim(a: &[f64], b: &[f64], w: usize, h: usize) -> Vec<f64> {
    const C1: f64 = 0.01 * 0.01;
    const C2: f64 = 0.03 * 0.03;
    let product =
        |x: &[f64], y: &[f64]| -> Vec<f64> { x.iter().zip(y).map(|(p, q)| p * q).collect() };
    let (ma, mb) = (gaussian_blur(a, w, h), gaussian_blur(b, w, h));
    let saa = gaussian_blur(&product(a, a), w, h);
    let sbb = gaussian_blur(&product(b, b), w, h);
    let sab = gaussian_blur(&product(a, b), w, h);
    (0..w * h)
        .map(|i| {
            let (ma, mb) = (ma[i], mb[i]);
            let va = (saa[i] - ma * ma).max(0.0);
            let vb = (sbb[i] - mb * mb).max(0.0);
            let cov = sab[i] - ma * mb;
            ((2.0 * ma * mb + C1) * (2.0 * cov + C2)) / ((ma * ma + mb * mb + C1) * (va + vb + C2))
        })
        .collect()
}

/// `f` averaged over an 11x11 Gaussian window of deviation 1.5 pixels (separably), the window
/// clipped at the image's borders and its weights renormalised there.
fn gaussian_blur(f: &[f64], w: usize, h: usize) -> Vec<f64> {
    const R: i64 = 5;
    const SIGMA: f64 = 1.5;
    let weights: Vec<f64> = (-R..=R)
        .map(|k| (-((k * k) as f64) / (2.0 * SIGMA * SIGMA)).exp())
        .collect();
    // One pass along rows (`step` 1, `len` w) or columns (`step` w, `len` h).
    let pass = |src: &[f64], len: usize, lines: usize, step: usize, stride: usize| {
        let mut out = vec![0.0; src.len()];
        for line in 0..lines {
            for i in 0..len as i64 {
                let (mut sum, mut weight) = (0.0, 0.0);
                for (k, g) in (-R..=R).zip(&weights) {
                    let j = i + k;
                    if (0..len as i64).contains(&j) {
                        sum += g * src[line * stride + j as usize * step];
                        weight += g;
                    }
                }
                out[line * stride + i as usize * step] = sum / weight;
            }
        }
        out
    };
    let rows = pass(f, w, h, 1, w);
    pass(&rows, h, w, w, 1)
}

/// The frame's own normals, or where it has none, normals from its depth by the cross product
/// of the smaller-step differences to the neighbouring pixels (as the pyramid estimates them
/// on its levels).
fn normals_of(frame: &Frame, tan_half: [f32; 2]) -> Vec<Option<Vec3>> {
    let (w, h) = (frame.width as i64, frame.height as i64);
    let point = |x: i64, y: i64| -> Option<Vec3> {
        if x < 0 || y < 0 || x >= w || y >= h {
            return None;
        }
        let (d, _) = frame.surface[(y * w + x) as usize]?;
        let ndc_x = (x as f32 + 0.5) / w as f32 * 2.0 - 1.0;
        let ndc_y = 1.0 - (y as f32 + 0.5) / h as f32 * 2.0;
        Some(Vec3::new(
            ndc_x * tan_half[0] * d,
            ndc_y * tan_half[1] * d,
            -d,
        ))
    };
    let step = |p: Vec3, a: Option<Vec3>, b: Option<Vec3>| match (a, b) {
        (Some(a), Some(b)) if (a.z - p.z).abs() <= (p.z - b.z).abs() => Some(a - p),
        (Some(_), Some(b)) | (None, Some(b)) => Some(p - b),
        (Some(a), None) => Some(a - p),
        (None, None) => None,
    };
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (_, own) = frame.surface[(y * w + x) as usize]?;
            if own.is_some() {
                return own;
            }
            let p = point(x, y)?;
            let dx = step(p, point(x + 1, y), point(x - 1, y))?;
            let dy = step(p, point(x, y + 1), point(x, y - 1))?;
            dy.cross(dx).try_normalize()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ssim_is_wangs_over_an_11_pixel_gaussian_window() {
        let (w, h) = (32, 32);
        // Two flat images: luminance term alone, (2 μa μb + C1) / (μa² + μb² + C1).
        let (a, b) = (vec![0.5; w * h], vec![0.6; w * h]);
        let want = (2.0 * 0.5 * 0.6 + 1e-4) / (0.25 + 0.36 + 1e-4);
        assert!(ssim(&a, &b, w, h).iter().all(|v| (v - want).abs() < 1e-12));
        // One pixel changed: the window reaches 5 pixels from its centre, not 6.
        let mut c = vec![0.5; w * h];
        c[16 * w + 16] = 1.0;
        let map = ssim(&a, &c, w, h);
        assert!(map[16 * w + 21] < 1.0 && map[21 * w + 16] < 1.0);
        assert_eq!(map[16 * w + 22], 1.0);
        assert_eq!(map[22 * w + 16], 1.0);
    }

    fn flat(w: u32, h: u32, rgb: [u8; 3]) -> Vec<u8> {
        (0..w * h)
            .flat_map(|_| [rgb[0], rgb[1], rgb[2], 255])
            .collect()
    }

    #[test]
    fn identical_frames_score_perfectly_and_empty_ones_are_all_holes() {
        let (w, h) = (16, 12);
        let rgba: Vec<u8> = (0..w * h * 4).map(|i| (i * 37 % 251) as u8).collect();
        let reference: Vec<Option<([f32; 3], f32)>> =
            (0..w * h).map(|_| Some(([0.0, 0.0, 1.0], 2.0))).collect();
        let same = Frame {
            width: w,
            height: h,
            rgba: &rgba,
            surface: (0..w * h).map(|_| Some((2.0, Some(Vec3::Z)))).collect(),
        };
        let m = compare(&rgba, &reference, &same, [0.5, 0.4]);
        assert_eq!(m.psnr, 100.0);
        assert!((m.ssim - 1.0).abs() < 1e-9, "{m:?}");
        assert_eq!(
            (m.depth_err, m.normal_err_deg, m.hole_rate, m.leak_rate),
            (0.0, 0.0, 0.0, 0.0)
        );

        let black = flat(w, h, [0, 0, 0]);
        let empty = Frame {
            width: w,
            height: h,
            rgba: &black,
            surface: vec![None; (w * h) as usize],
        };
        let m = compare(&rgba, &reference, &empty, [0.5, 0.4]);
        assert_eq!(m.hole_rate, 1.0);
        assert!(m.psnr < 10.0 && m.ssim < 0.5, "{m:?}");
        let (psnr, ssim) = albedo_scores(&rgba, &reference, &same, &rgba);
        assert_eq!(psnr, 100.0);
        assert!((ssim - 1.0).abs() < 1e-9);
        let (psnr, ssim) = albedo_scores(&rgba, &reference, &empty, &black);
        assert!(psnr < 10.0 && ssim < 0.5, "{psnr} {ssim}");
    }

    #[test]
    fn a_surface_behind_the_reference_is_a_leak_and_a_tilted_depth_has_a_normal_error() {
        let (w, h) = (8u32, 8u32);
        let rgba = flat(w, h, [100, 100, 100]);
        let reference: Vec<Option<([f32; 3], f32)>> = (0..w * h)
            .map(|i| (i % w < 4).then_some(([0.0, 0.0, 1.0], 1.0)))
            .collect();
        // Left half: the same plane at depth 1, seen through to depth 1.5 in one column;
        // right half: surface where the reference shows background.
        let surface = (0..w * h)
            .map(|i| {
                let x = i % w;
                Some((if x == 0 { 1.5 } else { 1.0 }, None))
            })
            .collect();
        let frame = Frame {
            width: w,
            height: h,
            rgba: &rgba,
            surface,
        };
        let m = compare(&rgba, &reference, &frame, [0.5, 0.5]);
        // 8 pixels behind + 32 over background, against 32 reference pixels.
        assert!((m.leak_rate - 40.0 / 32.0).abs() < 1e-9, "{m:?}");
        assert!(m.normal_err_deg > 1.0, "{m:?}");
    }
}
