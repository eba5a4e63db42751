//! A LAS file's creation date (LAS 1.4 R15: the day of the year, GMT, January 1 being day 1,
//! and the year): today's, as PDAL and LAStools write it. Day and year 0 are no date.

use std::time::{SystemTime, UNIX_EPOCH};

/// Today's (day of the year, year), in UTC.
pub fn today() -> (u16, u16) {
    let days = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() / 86_400);
    day_of_year(days)
}

/// The (day of the year, year) of the day `days` after 1970-01-01.
pub fn day_of_year(mut days: u64) -> (u16, u16) {
    let mut year = 1970u64;
    loop {
        let leap =
            (year.is_multiple_of(4) && !year.is_multiple_of(100)) || year.is_multiple_of(400);
        let length = if leap { 366 } else { 365 };
        if days < length {
            return ((days + 1) as u16, year.min(u16::MAX as u64) as u16);
        }
        days -= length;
        year += 1;
    }
}

/// Today as `las`'s header builder takes it.
pub fn today_date() -> Option<chrono::NaiveDate> {
    let (day, year) = today();
    chrono::NaiveDate::from_yo_opt(i32::from(year), u32::from(day))
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
