//! Process facts and size parsing.

/// Peak resident set size of this process in bytes (VmHWM), if the platform reports it.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Parses sizes such as `512MiB`, `2GiB`, `1.5G`, `800M`, `65536`. Binary units either way.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let value: f64 = num
        .parse()
        .map_err(|_| format!("\"{s}\" is not a size (examples: 512MiB, 2GiB, 1000000)"))?;
    let mult: u64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "k" | "kb" | "kib" => 1 << 10,
        "m" | "mb" | "mib" => 1 << 20,
        "g" | "gb" | "gib" => 1 << 30,
        "t" | "tb" | "tib" => 1 << 40,
        u => {
            return Err(format!(
                "\"{s}\" has an unknown unit \"{u}\" (use KiB, MiB, GiB)"
            ));
        }
    };
    let bytes = value * mult as f64;
    // The cast would saturate silently.
    if bytes >= u64::MAX as f64 {
        return Err(format!("\"{s}\" is too large a size"));
    }
    Ok(bytes as u64)
}

/// The least `--memory-limit` the converter can keep to: what it reserves for itself and one
/// small chunk.
pub const MIN_MEMORY_LIMIT: u64 = 64 << 20;

/// `parse_size` of a conversion's memory limit, refused below `MIN_MEMORY_LIMIT` rather than
/// silently raised.
pub fn parse_memory_limit(s: &str) -> Result<u64, String> {
    let bytes = parse_size(s)?;
    if bytes < MIN_MEMORY_LIMIT {
        return Err(format!(
            "{} is less than the {} a conversion needs at least",
            format_bytes(bytes),
            format_bytes(MIN_MEMORY_LIMIT)
        ));
    }
    Ok(bytes)
}

/// Human-readable byte count.
pub fn format_bytes(b: u64) -> String {
    bytes_with_decimals(b, 1)
}

fn bytes_with_decimals(b: u64, decimals: usize) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < units.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.decimals$} {}", units[u])
    }
}

/// Sizes `a` and `b` as `format_bytes` writes them, with as many more decimals as it takes to
/// tell them apart ("needs 1.3 MiB, only 1.3 MiB free" says nothing), down to single bytes.
pub fn format_bytes_apart(a: u64, b: u64) -> (String, String) {
    for decimals in 1..=3 {
        let pair = (
            bytes_with_decimals(a, decimals),
            bytes_with_decimals(b, decimals),
        );
        if pair.0 != pair.1 || a == b {
            return pair;
        }
    }
    (format!("{a} B"), format!("{b} B"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_in_binary_units() {
        assert_eq!(parse_size("512MiB"), Ok(512 << 20));
        assert_eq!(parse_size("2G"), Ok(2 << 30));
        assert_eq!(parse_size("1.5 GiB"), Ok(3 << 29));
        assert_eq!(parse_size("4096"), Ok(4096));
        assert!(parse_size("lots").is_err());
        assert!(parse_size("5 parsecs").is_err());
        assert!(parse_size("18446744073709551615GiB").is_err());
        assert_eq!(parse_memory_limit("64MiB"), Ok(64 << 20));
        // Two sizes shown alike get the decimals that tell them apart.
        assert_eq!(
            format_bytes_apart(1_363_148, 1_341_000),
            ("1.30 MiB".into(), "1.28 MiB".into())
        );
        assert_eq!(
            format_bytes_apart(1_048_577, 1_048_576),
            ("1048577 B".into(), "1048576 B".into())
        );
        assert_eq!(
            format_bytes_apart(3 << 30, 1 << 20),
            ("3.0 GiB".into(), "1.0 MiB".into())
        );
        for small in ["0", "1KiB", "63MiB"] {
            let e = parse_memory_limit(small).expect_err(small);
            assert!(e.contains("less than the 64.0 MiB"), "{e}");
        }
    }
}
