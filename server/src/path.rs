//! Splitting a request path into segments, refusing anything that could leave the served
//! directory: `..`, percent-encoded separators and dots, absolute and empty segments, hidden
//! names. Symlinks are the catalog's concern.

use percent_encoding::percent_decode_str;

#[derive(Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The path is malformed or tries to leave the directory (400).
    BadPath(&'static str),
    /// Nothing there (404).
    NotFound,
}

/// Checks the raw request path and returns the relative segments it names.
pub fn segments(raw: &str) -> Result<Vec<String>, Refusal> {
    let lower = raw.to_ascii_lowercase();
    if lower.contains("%2f") || lower.contains("%5c") || lower.contains("%00") {
        return Err(Refusal::BadPath("encoded separator"));
    }
    let decoded = percent_decode_str(raw)
        .decode_utf8()
        .map_err(|_| Refusal::BadPath("not UTF-8"))?;
    let Some(rest) = decoded.strip_prefix('/') else {
        return Err(Refusal::BadPath("not absolute-path form"));
    };
    if rest.is_empty() {
        return Ok(Vec::new());
    }
    let mut out = Vec::new();
    for seg in rest.split('/') {
        if seg.is_empty() {
            return Err(Refusal::BadPath("empty segment"));
        }
        if seg == "." || seg == ".." {
            return Err(Refusal::BadPath("dot segment"));
        }
        if seg.contains('\\') || seg.contains('\0') || seg.contains(':') {
            return Err(Refusal::BadPath("separator in a segment"));
        }
        if seg.starts_with('.') {
            return Err(Refusal::NotFound);
        }
        out.push(seg.to_string());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn traversal_forms_are_refused() {
        for raw in [
            "/../etc/passwd",
            "/a/../../etc",
            "/%2e%2e/etc/passwd",
            "/%2E%2E%2Fetc",
            "/a%2fb",
            "/a%5c..%5cb",
            "//etc/passwd",
            "/a//b",
            "/./a",
            "/a/%2e",
            "/c:/windows",
            "/a%00b",
        ] {
            assert!(segments(raw).is_err(), "{raw} was accepted");
        }
        assert_eq!(
            segments("/city.strata/octree.bin"),
            Ok(vec!["city.strata".to_string(), "octree.bin".to_string()])
        );
        assert_eq!(
            segments("/my%20scan/x"),
            Ok(vec!["my scan".into(), "x".into()])
        );
        assert_eq!(segments("/"), Ok(vec![]));
    }
}
