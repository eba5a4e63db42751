//! A LAS file's creation date (LAS 1.4 R15: the day of the year, GMT, January 1 being day 1,
//! and the year): today's, as PDAL and LAStools write it. Day and year 0 are no date.

use chrono::{Datelike, NaiveDate};
use std::time::{SystemTime, UNIX_EPOCH};

/// Days from 0001-01-01 (chrono's day 1 of the common era) to 1970-01-01.
const EPOCH_FROM_CE: i64 = 719_163;

/// Today's (day of the year, year), in UTC; (0, 0) where the clock says no date after 1970.
/// `SOURCE_DATE_EPOCH` (seconds since 1970, the reproducible-builds convention) stands for
/// the clock where it is set to one, so that a file written twice is the same byte for byte.
pub fn today() -> (u16, u16) {
    if let Some(secs) = std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
    {
        return day_of_year(secs / 86_400);
    }
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or((0, 0), |d| day_of_year(d.as_secs() / 86_400))
}

/// The (day of the year, year) of the day `days` after 1970-01-01.
pub fn day_of_year(days: u64) -> (u16, u16) {
    i64::try_from(days)
        .ok()
        .and_then(|d| i32::try_from(d + EPOCH_FROM_CE).ok())
        .and_then(NaiveDate::from_num_days_from_ce_opt)
        .and_then(|d| Some((d.ordinal() as u16, u16::try_from(d.year()).ok()?)))
        .unwrap_or((0, 0))
}

/// Today as `las`'s header builder takes it.
pub fn today_date() -> Option<NaiveDate> {
    let (day, year) = today();
    NaiveDate::from_yo_opt(i32::from(year), u32::from(day))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn days_count_from_the_first_of_january_as_day_one() {
        assert_eq!(day_of_year(0), (1, 1970));
        assert_eq!(day_of_year(364), (365, 1970));
        assert_eq!(day_of_year(365), (1, 1971));
        // 2000 is a leap year (divisible by 400): 2000-12-31 is its day 366.
        let to_2000 = (1970..2000)
            .map(|y| if y % 4 == 0 { 366 } else { 365 })
            .sum::<u64>();
        assert_eq!(day_of_year(to_2000 + 365), (366, 2000));
        assert_eq!(day_of_year(to_2000 + 366), (1, 2001));
        // 2026-12-06: day 340.
        assert_eq!(day_of_year(20_793), (340, 2026));
    }
}
