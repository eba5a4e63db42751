//! The `Range` header: one byte range, or a refusal.

#[derive(Debug, PartialEq, Eq)]
pub enum RangeRequest {
    /// No (usable) Range header: the whole file.
    Whole,
    /// Bytes `start..end` (end exclusive).
    Part { start: u64, end: u64 },
    /// Cannot be satisfied (past the end, or several ranges): 416.
    Unsatisfiable,
}

/// Parses `bytes=a-b`, `bytes=a-` and `bytes=-n` against a file of `len` bytes. Several ranges
/// are refused with 416; a header in another unit is ignored (RFC 9110 allows serving 200).
pub fn parse_range(header: Option<&str>, len: u64) -> RangeRequest {
    let Some(h) = header else {
        return RangeRequest::Whole;
    };
    let Some(spec) = h.trim().strip_prefix("bytes=") else {
        return RangeRequest::Whole;
    };
    if spec.contains(',') {
        return RangeRequest::Unsatisfiable;
    }
    let Some((a, b)) = spec.trim().split_once('-') else {
        return RangeRequest::Unsatisfiable;
    };
    let (a, b) = (a.trim(), b.trim());
    let parse = |s: &str| s.parse::<u64>().ok();
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
        for bad in [
            "bytes=100-",
            "bytes=5-2",
            "bytes=0-1,5-6",
            "bytes=-0",
            "bytes=x-",
            "bytes=-",
        ] {
            assert_eq!(
                parse_range(Some(bad), 100),
                RangeRequest::Unsatisfiable,
                "{bad}"
            );
        }
    }
}
