//! The dataset's one scale and offset: one step on every axis, the common step of the inputs'
//! resolutions, and exact integer positions wherever the inputs share a grid.

use crate::input::Precision;
use strata_format::number;

/// What the scan learned of one input.
#[derive(Debug, Clone)]
pub struct SourceExtent {
    pub precision: Precision,
    pub min: [f64; 3],
    pub max: [f64; 3],
}

#[derive(Debug, Clone, PartialEq)]
pub struct Quantization {
    pub scale: [f64; 3],
    pub offset: [f64; 3],
    /// Set when a step an input declares (a LAS scale, an E57 resolution, the difference of
    /// two LAS offsets) is no whole number of the step taken: its positions are rounded.
    pub coarsened: bool,
    /// Why, where `coarsened`: the extent does not fit 32 bits at the inputs' own steps, or
    /// their grids share no decimal step.
    pub coarse_grids: Option<String>,
    /// Said where floating-point inputs are stored in steps over one unit: their magnitude
    /// set the step, and points nearer each other than it become one position (one far
    /// outlier does that to all the rest).
    pub coarse_floats: Option<String>,
}

fn too_far(a: usize, min: [f64; 3], max: [f64; 3]) -> String {
    format!(
        "the points' {} coordinates span {} to {}, which no scale can store in 32-bit positions",
        ["x", "y", "z"][a],
        min[a],
        max[a]
    )
}

fn pow10_floor(v: f64) -> f64 {
    pow10(v.log10().floor() as i32)
}

/// `step` × 10^`e` as the decimal `step` is written in (1e-9 three times is 1e-6, not the
/// product's 1.0000000000000002e-6).
fn tenfold(step: f64, e: i32) -> f64 {
    let written = format!("{step:e}");
    let shifted = written.split_once('e').and_then(|(mantissa, exp)| {
        let exp: i32 = exp.parse().ok()?;
        format!("{mantissa}e{}", exp + e).parse().ok()
    });
    shifted.unwrap_or(f64::INFINITY)
}

/// 10^e, correctly rounded (as the decimal literal `1e{e}` is; `powi` may be a unit off).
fn pow10(e: i32) -> f64 {
    format!("1e{e}").parse().unwrap_or(f64::INFINITY)
}

/// The largest step that every one of `steps` is a whole number of, as the decimals they are
/// written in (0.01 and 0.001: 0.001; 0.0025 and 0.003: 0.0005), so that inputs on each of
/// those grids keep their positions exactly; the smallest of them where no decimal step is
/// (a third). 1 where there are none.
fn common_step(steps: impl Iterator<Item = f64> + Clone) -> f64 {
    let smallest = steps.clone().fold(f64::INFINITY, f64::min);
    if !smallest.is_finite() {
        return 1.0;
    }
    for e in -20..=20 {
        let unit = pow10(-e);
        let whole: Option<Vec<u64>> = steps
            .clone()
            .map(|s| {
                let k = s / unit;
                let n = k.round();
                // Within the rounding of the division (1e-13 of it), so that a third, or 0.01
                // rounded through single precision, is no decimal.
                ((k - n).abs() <= 1e-13 * n + 1e-9 && (1.0..=1e12).contains(&n)).then_some(n as u64)
            })
            .collect();
        if let Some(whole) = whole {
            let g = whole.into_iter().fold(0, gcd);
            return tenfold(g as f64, -e);
        }
    }
    smallest
}

/// Whether `coarse` is a whole number of `step`s, within the rounding of the division.
fn whole_multiple(coarse: f64, step: f64) -> bool {
    let k = coarse / step;
    let n = k.round();
    n >= 1.0 && (k - n).abs() <= 1e-9 * n
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// The scale that keeps a float coordinate of magnitude `max_abs` to within half its unit in
/// the last place: the largest power of ten not above one ULP.
pub(crate) fn float_scale(max_abs: f64, mantissa_bits: i32) -> f64 {
    let m = max_abs.max(1e-30);
    let ulp = 2f64.powi(m.log2().floor() as i32 - mantissa_bits);
    pow10_floor(ulp)
}

/// Chooses scale and offset for inputs with the given extents (`min`/`max`: all points).
/// Fails, naming the axis, when no finite scale fits the extent into 32-bit positions.
pub fn choose(
    sources: &[SourceExtent],
    min: [f64; 3],
    max: [f64; 3],
) -> Result<Quantization, String> {
    // Every step an input asks on any axis, and those it declares (a LAS scale, an E57
    // resolution, integers): only a step of which a declared one is not a whole number loses
    // what an input holds. A float's own resolution depends on its magnitude and is no promise
    // of precision; its loss is `coarse_floats`.
    let mut asked = Vec::new();
    let mut declared = Vec::new();
    for s in sources {
        for a in 0..3 {
            let max_abs = s.min[a].abs().max(s.max[a].abs());
            let (sa, is_declared) = match s.precision {
                Precision::Scaled { scale, .. } => (scale[a].abs(), true),
                // Zero on this axis everywhere: it asks no step (a tiny one would become 0
                // in a reader's single precision).
                Precision::Float32 | Precision::Float64 if max_abs == 0.0 => continue,
                Precision::Float32 => (float_scale(max_abs, 23), false),
                Precision::Float64 => (float_scale(max_abs, 52), false),
                Precision::Integer => (1.0, true),
                Precision::Resolution(step) => (step[a].abs(), true),
            };
            asked.push(sa);
            if is_declared {
                declared.push(sa);
            }
        }
    }
    // The grid of the scaled inputs (LAS, whose records are integers on it): the first one's
    // origin. Another's offset differs from it by a whole number of steps only if the step
    // divides the difference too. Float inputs have no grid: the points' minimum on the step.
    let first_scaled = sources.iter().find_map(|s| match s.precision {
        Precision::Scaled { offset, .. } => Some(offset),
        _ => None,
    });
    for s in sources {
        if let (Precision::Scaled { offset, .. }, Some(first)) = (s.precision, first_scaled) {
            for a in 0..3 {
                let d = (offset[a] - first[a]).abs();
                if d > 0.0 && d.is_finite() {
                    asked.push(d);
                    declared.push(d);
                }
            }
        }
    }
    // One step on every axis: the octree's cubes are cubes in integer positions (SPEC section
    // 3), so a step ten times finer on one axis than another makes every node, and every inner
    // node's sampling grid, ten times longer along it (floats of magnitude 1.0 and 0.9 ask 1e-7
    // and 1e-8). The finest is the common step of all asked; `grid`, of the declared ones, is
    // the coarsest that loses nothing an input declares.
    let finest = common_step(asked.iter().copied());
    let grid = (!declared.is_empty()).then(|| common_step(declared.iter().copied()));
    let origin: [f64; 3] = std::array::from_fn(|a| match first_scaled {
        Some(o) => o[a],
        None => (min[a] / finest).floor() * finest,
    });
    let fits = |a: usize, off: f64, sc: f64| {
        let lo = ((min[a] - off) / sc).round();
        let hi = ((max[a] - off) / sc).round();
        // NaN (an infinite span) fails both comparisons, as it must.
        lo >= i32::MIN as f64 && hi <= i32::MAX as f64
    };
    // The offset on an axis where the step does not fit from the grid's origin: the middle of
    // the data in whole steps from that origin, so that positions on the grid at the step stay
    // on it (where the step count is a number at all).
    let offset_for = |a: usize, step: f64| {
        if fits(a, origin[a], step) {
            return origin[a];
        }
        let mid = min[a] / 2.0 + max[a] / 2.0;
        let moved = origin[a] + ((mid - origin[a]) / step).round() * step;
        if moved.is_finite() { moved } else { mid }
    };
    let fitted = |step: f64| {
        let offset: [f64; 3] = std::array::from_fn(|a| offset_for(a, step));
        (0..3).all(|a| fits(a, offset[a], step)).then_some(offset)
    };
    // Where the finest does not fit 32 bits, coarser steps in tenfolds (as decimals: a product
    // of repeated tenfolds drifts, 9.999999999999998e-8): first those of the finest that keep
    // every declared grid, up to `grid` itself, then tenfolds of `grid`, which lose some. From
    // the smallest normal f64 to the largest takes about 616 passes, so the bound only stops
    // what could never fit.
    let keeps_grid = |step: f64| grid.is_none_or(|g| whole_multiple(g, step));
    let candidates = (0..700)
        .map(|k| tenfold(finest, k))
        .take_while(|&step| step.is_finite() && grid.is_none_or(|g| step < g))
        .filter(|&step| keeps_grid(step))
        .chain(grid)
        .chain((1..700).map(|k| tenfold(grid.unwrap_or(finest), k)));
    let mut chosen = None;
    for step in candidates {
        if !step.is_finite() {
            break;
        }
        if let Some(offset) = fitted(step) {
            chosen = Some((step, offset));
            break;
        }
    }
    let widest = (0..3)
        .max_by(|&a, &b| (max[a] - min[a]).total_cmp(&(max[b] - min[b])))
        .unwrap_or(0);
    let Some((step, offset)) = chosen else {
        return Err(too_far(widest, min, max));
    };
    if let Some(a) = (0..3).find(|&a| !(step.is_normal() && offset[a].is_finite())) {
        return Err(too_far(a, min, max));
    }
    let coarsened = declared.iter().any(|&d| !whole_multiple(d, step));
    let coarse_grids = coarsened.then(|| {
        if grid.is_some_and(|g| step > g) {
            format!(
                "the inputs span too far for 32-bit positions at their own resolution; scale \
                 coarsened to {step:e} on every axis, so positions are rounded to that step"
            )
        } else {
            format!(
                "the inputs' grids (their scales and offsets) share no decimal step; positions \
                 are stored in steps of {step:e}, and those of an input off that grid are \
                 rounded to it"
            )
        }
    });
    let scale = [step; 3];
    // Points apart from each other that all fall on one position would be one point: refused,
    // not quietly merged (floats spanning 1e-300, far below the finest step a float asks).
    let span = |a: usize| max[a] - min[a];
    if (0..3).any(|a| span(a) > 0.0) && (0..3).all(|a| span(a) < scale[a] / 2.0) {
        let widest = (0..3).map(span).fold(0.0, f64::max);
        return Err(format!(
            "the points lie within {widest:e} of each other on every axis, below the finest step \
             a dataset stores them in ({:e}): they would all become one position",
            scale.iter().copied().fold(f64::INFINITY, f64::min)
        ));
    }
    // Coarsened for the widest axis's sake beyond twice another axis's whole extent, a step
    // leaves that axis one or two positions: it is lost, not rounded.
    if grid.is_some_and(|g| step > g)
        && let Some(a) = (0..3).find(|&a| span(a) > 0.0 && span(a) < scale[a] / 2.0)
    {
        return Err(format!(
            "the points' {} coordinates span {}, which 32-bit positions hold only in steps of \
             {}, more than twice the whole {} the {} coordinates span: every point would get \
             one of at most two {} values",
            ["x", "y", "z"][widest],
            number(span(widest)),
            number(step),
            number(span(a)),
            ["x", "y", "z"][a],
            ["x", "y", "z"][a]
        ));
    }
    let floats = sources
        .iter()
        .any(|s| matches!(s.precision, Precision::Float32 | Precision::Float64));
    let coarse_floats = (floats && step > 1.0).then(|| {
        let spans: Vec<String> = (0..3)
            .map(|a| format!("{} {:e} to {:e}", ["x", "y", "z"][a], min[a], max[a]))
            .collect();
        format!(
            "floating-point coordinates stored in steps of {step:e} (the points span {}): points \
             nearer each other than a step become one position; a point far from all others (an \
             outlier) makes the step that large",
            spans.join(", ")
        )
    });
    Ok(Quantization {
        scale,
        offset,
        coarsened,
        coarse_grids,
        coarse_floats,
    })
}

impl Quantization {
    #[inline]
    pub fn quantize(&self, p: &[f64; 3]) -> [i32; 3] {
        [
            ((p[0] - self.offset[0]) / self.scale[0]).round() as i32,
            ((p[1] - self.offset[1]) / self.scale[1]).round() as i32,
            ((p[2] - self.offset[2]) / self.scale[2]).round() as i32,
        ]
    }
}

#[cfg(test)]
#[path = "quantize_tests.rs"]
mod tests;
