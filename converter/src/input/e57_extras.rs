//! The fields of an E57 scan that the `e57` crate's simple reader does not give: return index
//! and count, and time stamps. They are read with the crate's raw reader, on a second reader
//! of the same file walking the same records in step with the simple one.

use e57::{E57Reader, PointCloud, RecordName, RecordValue};
use std::fs::File;
use std::io::BufReader;
use std::path::Path;
use strata_format::TimeBase;

/// Seconds between standard GPS time (an E57 `acquisitionStart`) and adjusted standard GPS
/// time, the time base the dataset's `gps_time` takes from it.
const ADJUSTED_STANDARD: f64 = 1e9;

/// What a file's scans hold beyond positions, colour and intensity.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FileExtras {
    /// Some scan has a return index or count.
    pub returns: bool,
    /// Some scan has time stamps; with the base where every such scan states when it began.
    pub time: Option<Option<TimeBase>>,
}

impl FileExtras {
    pub fn of(clouds: &[PointCloud]) -> FileExtras {
        let timed: Vec<&PointCloud> = clouds
            .iter()
            .filter(|pc| has(pc, RecordName::TimeStamp))
            .collect();
        FileExtras {
            returns: clouds
                .iter()
                .any(|pc| has(pc, RecordName::ReturnIndex) || has(pc, RecordName::ReturnCount)),
            time: (!timed.is_empty()).then(|| {
                timed
                    .iter()
                    .all(|pc| pc.acquisition_start.is_some())
                    .then_some(TimeBase::GpsAdjustedStandard)
            }),
        }
    }

    /// Whether the time stamps become GPS time: only where every timed scan states its
    /// start, so that one column never holds two kinds of time.
    pub fn absolute_time(&self) -> bool {
        self.time == Some(Some(TimeBase::GpsAdjustedStandard))
    }

    /// Warnings for scans whose time stamps count from a start the file does not give (then
    /// every scan's stamps are kept as stored).
    pub fn warnings(path: &Path, clouds: &[PointCloud]) -> Vec<String> {
        let n = clouds.len();
        clouds
            .iter()
            .enumerate()
            .filter(|(_, pc)| has(pc, RecordName::TimeStamp) && pc.acquisition_start.is_none())
            .map(|(i, _)| {
                format!(
                    "{}: scan {i} of {n} has time stamps but no acquisitionStart: they are \
                     seconds from a start the file does not give, so every scan's stamps are \
                     kept as stored, and gps_time states no time base",
                    path.display()
                )
            })
            .collect()
    }
}

fn has(pc: &PointCloud, name: RecordName) -> bool {
    pc.prototype.iter().any(|r| r.name == name)
}

/// One point's extra fields.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointExtras {
    /// LAS's return number (1 for the first) and number of returns: 1 of 1 where the scan
    /// has neither.
    pub return_number: u8,
    pub number_of_returns: u8,
    /// Adjusted standard GPS time where every timed scan states its start; else the stamp as
    /// stored; 0 where the scan has no time stamps or this one is invalid.
    pub time: f64,
}

/// Where a scan's extra fields lie in its raw records, and its start.
pub struct ScanExtras {
    return_index: Option<usize>,
    return_count: Option<usize>,
    time: Option<usize>,
    time_invalid: Option<usize>,
    start: f64,
}

impl ScanExtras {
    /// `None` where the scan has none of the fields. `absolute`: whether its stamps become
    /// GPS time from its start (`FileExtras::absolute_time`).
    pub fn of(pc: &PointCloud, absolute: bool) -> Option<ScanExtras> {
        let at = |name: RecordName| pc.prototype.iter().position(|r| r.name == name);
        let e = ScanExtras {
            return_index: at(RecordName::ReturnIndex),
            return_count: at(RecordName::ReturnCount),
            time: at(RecordName::TimeStamp),
            time_invalid: at(RecordName::IsTimeStampInvalid),
            start: pc
                .acquisition_start
                .as_ref()
                .filter(|_| absolute)
                .map_or(0.0, |s| s.gps_time - ADJUSTED_STANDARD),
        };
        (e.return_index.is_some() || e.return_count.is_some() || e.time.is_some()).then_some(e)
    }

    /// A reader of the scan's raw records, on a reader of its own of the file at `path`.
    pub fn open(path: &Path) -> Result<E57Reader<BufReader<File>>, String> {
        let file = File::open(path).map_err(|e| format!("cannot open it again ({e})"))?;
        E57Reader::new(BufReader::with_capacity(1 << 20, file))
            .map_err(|e| format!("cannot read it again ({})", super::e57_decode::plain(&e)))
    }

    /// The extra fields of one raw record.
    pub fn read(&self, pc: &PointCloud, values: &[RecordValue]) -> Result<PointExtras, String> {
        let number = |i: usize| -> Result<f64, String> {
            let (v, r) = (values.get(i), pc.prototype.get(i));
            v.zip(r)
                .and_then(|(v, r)| v.to_f64(&r.data_type).ok())
                .ok_or_else(|| "a record is shorter than the scan's prototype".to_string())
        };
        let byte = |v: f64| v.round().clamp(0.0, 255.0) as u8;
        let index = self.return_index.map(number).transpose()?;
        let count = self.return_count.map(number).transpose()?;
        let return_number = index.map_or(1, |i| byte(i + 1.0));
        let number_of_returns = count.map_or(return_number, byte).max(return_number);
        let invalid = self.time_invalid.map(number).transpose()?.unwrap_or(0.0) != 0.0;
        let time = match self.time.map(number).transpose()? {
            Some(t) if !invalid && t.is_finite() => self.start + t,
            _ => 0.0,
        };
        Ok(PointExtras {
            return_number,
            number_of_returns,
            time,
        })
    }
}
