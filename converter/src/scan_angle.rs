//! A LAS scan angle in both of its forms, where one dataset holds both: legacy inputs (formats
//! 0 to 5) store `scan_angle_rank`, whole degrees in an i8; formats 6 to 10 store `scan_angle`,
//! steps of 0.006° in an i16. Merged, each input's points would leave the other form 0, which
//! reads as nadir: an export in formats 6 to 10 then gave the legacy points a scan angle of 0,
//! their real one in an extra field. Each point gets the form its input lacks from the one it
//! has instead.

use strata_format::{AttrType, Attribute};

const RANK: &str = "scan_angle_rank";
const STEPS: &str = "scan_angle";
/// Degrees per step of `scan_angle` (LAS 1.4).
const DEGREES_PER_STEP: f64 = 0.006;

/// Where a row holds the form an input has and the form it lacks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanAngleFill {
    from: usize,
    to: usize,
    /// `to` is `scan_angle` (from the rank), else `scan_angle_rank` (from the steps).
    to_steps: bool,
}

impl ScanAngleFill {
    /// The fill for an input of `input` attributes into rows of `dataset` attributes that
    /// start `base` bytes into the row, where the dataset holds both forms and the input one.
    pub fn for_input(input: &[Attribute], dataset: &[Attribute], base: usize) -> Option<Self> {
        let has = |name: &str, ty: AttrType| {
            input
                .iter()
                .any(|a| a.name == name && a.ty == ty && a.count == 1)
        };
        let at = |name: &str, ty: AttrType| {
            let mut at = base;
            for a in dataset {
                if a.name == name {
                    return (a.ty == ty && a.count == 1).then_some(at);
                }
                at += a.size();
            }
            None
        };
        let (rank, steps) = (at(RANK, AttrType::I8)?, at(STEPS, AttrType::I16)?);
        match (has(RANK, AttrType::I8), has(STEPS, AttrType::I16)) {
            (true, false) => Some(ScanAngleFill {
                from: rank,
                to: steps,
                to_steps: true,
            }),
            (false, true) => Some(ScanAngleFill {
                from: steps,
                to: rank,
                to_steps: false,
            }),
            _ => None,
        }
    }

    /// Writes the missing form into `row` from the present one.
    #[inline]
    pub fn apply(&self, row: &mut [u8]) {
        if self.to_steps {
            let degrees = f64::from(row[self.from] as i8);
            let steps = (degrees / DEGREES_PER_STEP).round() as i16;
            row[self.to..self.to + 2].copy_from_slice(&steps.to_le_bytes());
        } else {
            let steps = i16::from_le_bytes([row[self.from], row[self.from + 1]]);
            let degrees = (f64::from(steps) * DEGREES_PER_STEP).round();
            row[self.to] = degrees.clamp(-128.0, 127.0) as i8 as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_form_is_made_from_the_other() {
        let dataset = [
            Attribute::new("intensity", AttrType::U16, 1),
            Attribute::new(RANK, AttrType::I8, 1),
            Attribute::new(STEPS, AttrType::I16, 1),
        ];
        let legacy = [Attribute::new(RANK, AttrType::I8, 1)];
        let fill = ScanAngleFill::for_input(&legacy, &dataset, 12).expect("legacy fill");
        let mut row = vec![0u8; 12 + 5];
        row[14] = (-45i8) as u8;
        fill.apply(&mut row);
        assert_eq!(i16::from_le_bytes([row[15], row[16]]), -7500);
        let extended = [Attribute::new(STEPS, AttrType::I16, 1)];
        let fill = ScanAngleFill::for_input(&extended, &dataset, 12).expect("extended fill");
        let mut row = vec![0u8; 17];
        row[15..17].copy_from_slice(&8667i16.to_le_bytes());
        fill.apply(&mut row);
        assert_eq!(row[14] as i8, 52);
        // Both forms, or a dataset of one: nothing to fill.
        assert!(ScanAngleFill::for_input(&dataset, &dataset, 12).is_none());
        assert!(ScanAngleFill::for_input(&legacy, &legacy, 12).is_none());
    }
}
