//! The `Range` header: one byte range, or a refusal.

#[derive(Debug, PartialEq, Eq)]
pub enum RangeRequest {
    /// No (usable) Range header: the whole file.
    Whole,
    /// Bytes `start..end` (end exclusive).
    Part { start: u64, end: u64 },
    /// Cannot be satisfied (every range past the end, or malformed): 416.
    Unsatisfiable,
}

/// Parses `bytes=a-b`, `bytes=a-` and `bytes=-n` against a file of `len` bytes (the unit in
/// any case, empty list elements skipped, RFC 9110 section 14). Several ranges are served as
/// the whole file (RFC 9110 lets a server ignore Range, and this one sends no multipart
/// answers) unless none of them can be satisfied, which is 416 (section 15.5.17); a header in
/// another unit is ignored.
pub fn parse_range(header: Option<&str>, len: u64) -> RangeRequest {
    let Some(h) = header else {
        return RangeRequest::Whole;
    };
    let h = h.trim();
    let Some(spec) = h
        .get(..6)
        .filter(|unit| unit.eq_ignore_ascii_case("bytes="))
        .map(|_| &h[6..])
    else {
        return RangeRequest::Whole;
    };
    let mut ranges = spec.split(',').map(str::trim).filter(|r| !r.is_empty());
    match (ranges.next(), ranges.next()) {
        (None, _) => RangeRequest::Unsatisfiable,
        (Some(one), None) => one_range(one, len),
        (Some(one), Some(two)) => {
            let mut all = [one, two].into_iter().chain(ranges);
            if all.any(|r| matches!(one_range(r, len), RangeRequest::Part { .. })) {
                RangeRequest::Whole
            } else {
                RangeRequest::Unsatisfiable
            }
        }
    }
}

/// One range of a `bytes=` list against a file of `len` bytes.
fn one_range(one: &str, len: u64) -> RangeRequest {
    let Some((a, b)) = one.split_once('-') else {
        return RangeRequest::Unsatisfiable;
    };
    let (a, b) = (a.trim(), b.trim());
    // Digits only; a number past u64 is a position past any file's end.
    let parse = |s: &str| {
        (!s.is_empty() && s.bytes().all(|c| c.is_ascii_digit()))
            .then(|| s.parse::<u64>().unwrap_or(u64::MAX))
    };
    let (start, end) = match (a.is_empty(), b.is_empty()) {
        (true, false) => match parse(b) {
            Some(0) | None => return RangeRequest::Unsatisfiable,
            Some(n) => (len.saturating_sub(n), len),
        },
        (false, true) => match parse(a) {
            Some(s) => (s, len),
            None => return RangeRequest::Unsatisfiable,
        },
        (false, false) => match (parse(a), parse(b)) {
            (Some(s), Some(e)) if s <= e => (s, e.saturating_add(1).min(len)),
            _ => return RangeRequest::Unsatisfiable,
        },
        (true, true) => return RangeRequest::Unsatisfiable,
    };
    if start >= len || start >= end {
        return RangeRequest::Unsatisfiable;
    }
    RangeRequest::Part { start, end }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_as_rfc_9110_says() {
        let part = |start, end| RangeRequest::Part { start, end };
        assert_eq!(parse_range(None, 100), RangeRequest::Whole);
        assert_eq!(parse_range(Some("bytes=0-9"), 100), part(0, 10));
        assert_eq!(parse_range(Some("bytes=90-"), 100), part(90, 100));
        assert_eq!(parse_range(Some("bytes=-10"), 100), part(90, 100));
        assert_eq!(parse_range(Some("bytes=-500"), 100), part(0, 100));
        assert_eq!(parse_range(Some("bytes=95-200"), 100), part(95, 100));
        assert_eq!(parse_range(Some("items=0-1"), 100), RangeRequest::Whole);
        // The unit in any case, empty list elements, and positions past u64.
        assert_eq!(parse_range(Some("Bytes=0-9"), 100), part(0, 10));
        assert_eq!(parse_range(Some("bytes=0-9,"), 100), part(0, 10));
        assert_eq!(parse_range(Some("bytes=, 0-9"), 100), part(0, 10));
        assert_eq!(
            parse_range(Some("bytes=0-99999999999999999999"), 100),
            part(0, 100)
        );
        assert_eq!(
            parse_range(Some("bytes=-99999999999999999999"), 100),
            part(0, 100)
        );
        // Several ranges: the whole file where any can be satisfied, else 416.
        assert_eq!(parse_range(Some("bytes=0-1,5-6"), 100), RangeRequest::Whole);
        assert_eq!(
            parse_range(Some("bytes=200-,5-6"), 100),
            RangeRequest::Whole
        );
        assert_eq!(
            parse_range(Some("bytes=x-,-0,90-"), 100),
            RangeRequest::Whole
        );
        for bad in [
            "bytes=100-,200-300",
            "bytes=x-,-0",
            "bytes=100-",
            "bytes=5-2",
            "bytes=-0",
            "bytes=x-",
            "bytes=-",
            "bytes=+0-+9",
            "bytes=",
        ] {
            assert_eq!(
                parse_range(Some(bad), 100),
                RangeRequest::Unsatisfiable,
                "{bad}"
            );
        }
    }
}
