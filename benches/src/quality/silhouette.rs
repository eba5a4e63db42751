//! The silhouette error of a frame: how far, in pixels, its outline lies from the reference's.
//! Holes inside the object are not outline: only covered pixels next to the background that
//! reaches the image border count, so that this measures the outline and the hole rate the
//! holes. The background reaches the border through gaps wider than `CLOSING_PX` twice only:
//! a sparse frame's gaps between points join into paths to the border, and made most of its
//! covered pixels outline (half the pixels of a disc taken away at random read as a 3 pixel
//! error).

use std::collections::VecDeque;

/// The radius of the closing applied to both masks before their outlines are taken: gaps
/// narrower than twice this are filled (a concavity that narrow counts in neither outline).
const CLOSING_PX: f64 = 4.0;

/// Mean distance in pixels from each outline pixel of `frame` to the nearest of `reference`
/// and back, averaged over both ways; 0 where neither shows anything, the image's half
/// perimeter where only one does.
pub fn silhouette_error(reference: &[bool], frame: &[bool], w: usize, h: usize) -> f64 {
    let (reference, frame) = (closed(reference, w, h), closed(frame, w, h));
    let (ra, fa) = (outline(&reference, w, h), outline(&frame, w, h));
    let (rn, fn_) = (
        ra.iter().filter(|b| **b).count(),
        fa.iter().filter(|b| **b).count(),
    );
    match (rn, fn_) {
        (0, 0) => return 0.0,
        (0, _) | (_, 0) => return (w + h) as f64,
        _ => {}
    }
    let (to_r, to_f) = (distance_to(&ra, w, h), distance_to(&fa, w, h));
    let mean = |from: &[bool], to: &[f64], n: usize| {
        from.iter()
            .zip(to)
            .filter(|(b, _)| **b)
            .map(|(_, d)| *d)
            .sum::<f64>()
            / n as f64
    };
    0.5 * (mean(&fa, &to_r, fn_) + mean(&ra, &to_f, rn))
}

/// Covered pixels with a 4-neighbour (or the image edge) in the background that reaches the
/// border.
fn outline(covered: &[bool], w: usize, h: usize) -> Vec<bool> {
    let mut outside = vec![false; w * h];
    let mut queue = VecDeque::new();
    for i in 0..w * h {
        let (x, y) = (i % w, i / w);
        if (x == 0 || y == 0 || x == w - 1 || y == h - 1) && !covered[i] {
            outside[i] = true;
            queue.push_back(i);
        }
    }
    while let Some(i) = queue.pop_front() {
        let (x, y) = (i % w, i / w);
        let mut visit = |j: usize| {
            if !covered[j] && !outside[j] {
                outside[j] = true;
                queue.push_back(j);
            }
        };
        if x > 0 {
            visit(i - 1);
        }
        if x + 1 < w {
            visit(i + 1);
        }
        if y > 0 {
            visit(i - w);
        }
        if y + 1 < h {
            visit(i + w);
        }
    }
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            covered[i]
                && (x == 0
                    || y == 0
                    || x == w - 1
                    || y == h - 1
                    || outside[i - 1]
                    || outside[i + 1]
                    || outside[i - w]
                    || outside[i + w])
        })
        .collect()
}

/// `covered` closed by a disc of radius `CLOSING_PX` (dilated, then eroded), the image's
/// outside taken as background (a margin of it around the image while closing), so that
/// nothing is closed up to the border.
fn closed(covered: &[bool], w: usize, h: usize) -> Vec<bool> {
    if !covered.contains(&true) {
        return covered.to_vec();
    }
    let m = CLOSING_PX.ceil() as usize + 1;
    let (pw, ph) = (w + 2 * m, h + 2 * m);
    let mut padded = vec![false; pw * ph];
    for y in 0..h {
        padded[(y + m) * pw + m..(y + m) * pw + m + w]
            .copy_from_slice(&covered[y * w..(y + 1) * w]);
    }
    let background: Vec<bool> = distance_to(&padded, pw, ph)
        .into_iter()
        .map(|d| d > CLOSING_PX)
        .collect();
    let eroded = distance_to(&background, pw, ph);
    (0..w * h)
        .map(|i| eroded[(i / w + m) * pw + i % w + m] > CLOSING_PX)
        .collect()
}

/// Exact Euclidean distance from every pixel to the nearest `seed` pixel (Felzenszwalb and
/// Huttenlocher's separable transform).
fn distance_to(seeds: &[bool], w: usize, h: usize) -> Vec<f64> {
    const FAR: f64 = 1e20;
    let mut d: Vec<f64> = seeds.iter().map(|s| if *s { 0.0 } else { FAR }).collect();
    let mut line = Vec::new();
    for x in 0..w {
        line.clear();
        line.extend((0..h).map(|y| d[y * w + x]));
        for (y, v) in squared_1d(&line).into_iter().enumerate() {
            d[y * w + x] = v;
        }
    }
    for y in 0..h {
        let row = squared_1d(&d[y * w..(y + 1) * w]);
        d[y * w..(y + 1) * w].copy_from_slice(&row);
    }
    d.into_iter().map(f64::sqrt).collect()
}

/// The lower envelope of parabolas: min over q of (p - q)^2 + f(q), for every p.
fn squared_1d(f: &[f64]) -> Vec<f64> {
    let n = f.len();
    let mut out = vec![0.0; n];
    if n == 0 {
        return out;
    }
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0usize;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    let meet = |q: usize, r: usize| {
        let (qf, rf) = (q as f64, r as f64);
        ((f[q] + qf * qf) - (f[r] + rf * rf)) / (2.0 * qf - 2.0 * rf)
    };
    for q in 1..n {
        let mut s = meet(q, v[k]);
        while s <= z[k] {
            k -= 1;
            s = meet(q, v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let dq = q as f64 - v[k] as f64;
        *o = dq * dq + f[v[k]];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc(w: usize, h: usize, cx: f64, cy: f64, r: f64) -> Vec<bool> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
                (x - cx).powi(2) + (y - cy).powi(2) <= r * r
            })
            .collect()
    }

    #[test]
    fn a_disc_grown_by_three_pixels_is_three_pixels_off() {
        let (w, h) = (64, 64);
        let a = disc(w, h, 32.0, 32.0, 15.0);
        let b = disc(w, h, 32.0, 32.0, 18.0);
        let e = silhouette_error(&a, &b, w, h);
        assert!((e - 3.0).abs() < 0.6, "{e}");
        assert_eq!(silhouette_error(&a, &a, w, h), 0.0);
    }

    #[test]
    fn holes_inside_are_not_outline() {
        let (w, h) = (64, 64);
        let a = disc(w, h, 32.0, 32.0, 20.0);
        let mut b = a.clone();
        for y in 28..36 {
            for x in 28..36 {
                b[y * w + x] = false;
            }
        }
        assert_eq!(silhouette_error(&a, &b, w, h), 0.0);
    }

    #[test]
    fn gaps_between_points_are_not_outline() {
        // A disc with half its pixels taken away at random: its outline is still the disc's.
        let (w, h) = (96, 96);
        let a = disc(w, h, 48.0, 48.0, 30.0);
        let mut seed = 5u64;
        let b: Vec<bool> = a
            .iter()
            .map(|&c| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                c && (seed >> 63) == 0
            })
            .collect();
        let e = silhouette_error(&a, &b, w, h);
        assert!(e < 0.5, "{e}");
    }

    #[test]
    fn closing_does_not_reach_the_border() {
        // Rectangles 3 and 5 pixels from the image's left edge, 2 apart all round: the nearer
        // is not closed up to the border (its outline there would lie 5 from the other's).
        let (w, h) = (64, 64);
        let rect = |x0: usize, x1: usize, y0: usize, y1: usize| -> Vec<bool> {
            (0..w * h)
                .map(|i| (x0..x1).contains(&(i % w)) && (y0..y1).contains(&(i / w)))
                .collect()
        };
        let (a, b) = (rect(3, 40, 10, 54), rect(5, 38, 12, 52));
        let e = silhouette_error(&a, &b, w, h);
        assert!((e - 2.0).abs() < 0.2, "{e}");
    }

    #[test]
    fn distances_are_euclidean() {
        let (w, h) = (9, 9);
        let mut seeds = vec![false; w * h];
        seeds[4 * w + 4] = true;
        let d = distance_to(&seeds, w, h);
        assert_eq!(d[4 * w + 4], 0.0);
        assert!((d[7 * w + 8] - 5.0).abs() < 1e-9, "{}", d[7 * w + 8]);
    }
}
