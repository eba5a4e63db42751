//! Why no window opened, said as one sentence a user can act on.

/// The reason eframe gives for not opening a window, with the display it tried. winit's OS
/// errors carry the place in winit's source they were raised at ("os error at
/// /root/.cargo/registry/.../mod.rs:788: Failed to open connection to X server"), which tells
/// a user nothing: it is cut off.
pub fn window_failure(e: &eframe::Error) -> String {
    let text = without_source_location(&e.to_string());
    // The sentence goes on after it.
    let reason = text.trim_end_matches('.');
    let display = |name: &str| std::env::var(name).ok().filter(|v| !v.is_empty());
    match (display("DISPLAY"), display("WAYLAND_DISPLAY")) {
        (Some(x), Some(w)) => format!("{reason} (DISPLAY={x}, WAYLAND_DISPLAY={w})"),
        (Some(x), None) => format!("{reason} (DISPLAY={x})"),
        (None, Some(w)) => format!("{reason} (WAYLAND_DISPLAY={w})"),
        (None, None) => reason.to_string(),
    }
}

/// `text` without an "os error at FILE.rs:LINE: " and what comes before it.
fn without_source_location(text: &str) -> String {
    let Some(at) = text.find("os error at ") else {
        return text.to_string();
    };
    let rest = &text[at..];
    let reason = rest.find(".rs:").and_then(|rs| {
        let after = &rest[rs + 4..];
        let digits = after.find(|c: char| !c.is_ascii_digit())?;
        after[digits..].strip_prefix(": ")
    });
    match reason {
        Some(reason) if !reason.is_empty() => reason.to_string(),
        _ => text.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::without_source_location;

    #[test]
    fn the_source_location_of_an_os_error_is_cut_off() {
        let x = "winit EventLoopError: os error at /root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/winit-0.30.13/src/platform_impl/linux/mod.rs:788: Failed to open connection to X server";
        assert_eq!(
            without_source_location(x),
            "Failed to open connection to X server"
        );
        // Messages of another shape stay whole.
        let plain = "winit EventLoopError: the requested operation is not supported by Winit";
        assert_eq!(without_source_location(plain), plain);
        let odd = "os error at somewhere: no file named";
        assert_eq!(without_source_location(odd), odd);
    }
}
