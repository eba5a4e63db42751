//! The attributes the normal step reads and writes, wherever the layout holds them: `normal`
//! (octahedral 2 x u16, or the inputs' three floats), `radius` (f32) and `surface_variation`
//! (f16) unless the inputs already have them as floats, and `scanner` (which scan took the
//! point).

use crate::error::{ConvertError, Result};
use strata_format::{AttrType, Attribute, RowLayout, oct16_decode, oct16_encode};

pub const NORMAL: &str = "normal";
pub const RADIUS: &str = "radius";
pub const VARIATION: &str = "surface_variation";
pub const SCANNER: &str = "scanner";

/// The attributes to append to the inputs' for the step to write into.
pub fn added(inputs: &[Attribute]) -> Result<Vec<Attribute>> {
    let mut out = Vec::new();
    match inputs.iter().find(|a| a.name == NORMAL) {
        None => out.push(Attribute::oct16_normal()),
        Some(a) if a.is_oct16() || (a.count == 3 && a.ty.is_float()) => {}
        Some(a) => return Err(unusable(a, "three floats or octahedral 2 x u16")),
    }
    // The radius is in real units, which may be degrees (1e-7) or kilometres: beyond f16's
    // range (6e-5 to 65504), so f32. The variation lies in 0 to 1/3.
    for (name, ty, description) in [
        (
            RADIUS,
            AttrType::F32,
            "disc radius covering the surface at the local density",
        ),
        (
            VARIATION,
            AttrType::F16,
            "surface variation λ0 / (λ0 + λ1 + λ2)",
        ),
    ] {
        match inputs.iter().find(|a| a.name == name) {
            None => out.push(Attribute {
                description: description.into(),
                ..Attribute::new(name, ty, 1)
            }),
            Some(a) if a.count == 1 && a.ty.is_float() => {}
            Some(a) => return Err(unusable(a, "one float")),
        }
    }
    Ok(out)
}

fn unusable(a: &Attribute, want: &str) -> ConvertError {
    ConvertError::Usage(format!(
        "the inputs' attribute \"{}\" is {} x {}, but --normals writes it as {want}",
        a.name,
        a.count,
        a.ty.name()
    ))
}

/// Where in a row each attribute the step uses lies.
pub struct Targets {
    normal: (usize, Kind),
    radius: (usize, AttrType),
    variation: (usize, AttrType),
    scanner: Option<usize>,
}

#[derive(Clone, Copy)]
enum Kind {
    Oct16,
    Floats(AttrType),
}

impl Targets {
    pub fn find(layout: &RowLayout) -> Result<Targets> {
        let at = |name: &str| {
            layout.index_of(name).ok_or_else(|| {
                ConvertError::internal("estimating normals", format!("no \"{name}\" attribute"))
            })
        };
        let n = at(NORMAL)?;
        let a = &layout.attributes[n];
        let kind = if a.is_oct16() {
            Kind::Oct16
        } else {
            Kind::Floats(a.ty)
        };
        let (r, v) = (at(RADIUS)?, at(VARIATION)?);
        let scanner = layout.index_of(SCANNER).filter(|&i| {
            layout.attributes[i].ty == AttrType::U16 && layout.attributes[i].count == 1
        });
        Ok(Targets {
            normal: (layout.offsets[n], kind),
            radius: (layout.offsets[r], layout.attributes[r].ty),
            variation: (layout.offsets[v], layout.attributes[v].ty),
            scanner: scanner.map(|i| layout.offsets[i]),
        })
    }

    /// The bytes of the row's normal.
    fn normal_bytes(&self) -> std::ops::Range<usize> {
        let (at, kind) = self.normal;
        let len = match kind {
            Kind::Oct16 => 4,
            Kind::Floats(ty) => 3 * ty.size(),
        };
        at..at + len
    }

    /// The row's normal; `None` where it has none (all zero).
    pub fn normal(&self, row: &[u8]) -> Option<[f64; 3]> {
        let (at, kind) = self.normal;
        match kind {
            Kind::Oct16 => oct16_decode([
                u16::from_le_bytes([row[at], row[at + 1]]),
                u16::from_le_bytes([row[at + 2], row[at + 3]]),
            ]),
            Kind::Floats(ty) => {
                let s = ty.size();
                let n = [0, 1, 2].map(|c| ty.read_f64(&row[at + c * s..]));
                (n != [0.0; 3] && n.iter().all(|c| c.is_finite())).then_some(n)
            }
        }
    }

    /// Marks the row as having no normal: all zero, in either encoding (SPEC.md).
    pub fn put_no_normal(&self, row: &mut [u8]) {
        row[self.normal_bytes()].fill(0);
    }

    pub fn put_normal(&self, row: &mut [u8], n: [f64; 3]) {
        let (at, kind) = self.normal;
        match kind {
            Kind::Oct16 => {
                let [u, v] = oct16_encode(n);
                row[at..at + 2].copy_from_slice(&u.to_le_bytes());
                row[at + 2..at + 4].copy_from_slice(&v.to_le_bytes());
            }
            Kind::Floats(ty) => {
                for (c, value) in n.into_iter().enumerate() {
                    put_float(&mut row[at + c * ty.size()..], ty, value);
                }
            }
        }
    }

    /// The row's disc radius, where it holds one (an input's: positive and finite).
    pub fn radius(&self, row: &[u8]) -> Option<f64> {
        let (at, ty) = self.radius;
        let r = ty.read_f64(&row[at..]);
        (r > 0.0 && r.is_finite()).then_some(r)
    }

    pub fn put_radius(&self, row: &mut [u8], r: f64) {
        put_float(&mut row[self.radius.0..], self.radius.1, r);
    }

    pub fn put_variation(&self, row: &mut [u8], s: f64) {
        put_float(&mut row[self.variation.0..], self.variation.1, s);
    }

    /// The index of the scan that took the point, where the inputs say.
    pub fn scanner(&self, row: &[u8]) -> Option<usize> {
        self.scanner
            .map(|at| u16::from_le_bytes([row[at], row[at + 1]]) as usize)
    }
}

/// Writes `v` as float type `ty` at the start of `out` (only float types reach here).
fn put_float(out: &mut [u8], ty: AttrType, v: f64) {
    match ty {
        AttrType::F16 => out[..2].copy_from_slice(&half::f16::from_f64(v).to_le_bytes()),
        AttrType::F32 => out[..4].copy_from_slice(&(v as f32).to_le_bytes()),
        _ => out[..8].copy_from_slice(&v.to_le_bytes()),
    }
}
