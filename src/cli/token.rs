//! The bearer token of `--token` or `--token-file`, for `serve` and for every command that
//! reads a served dataset: checked alike (an empty or blank token refused, a file's newline
//! dropped), and from a file kept out of `ps`.

use anyhow::Context;
use std::path::Path;
use strata_server::check_token;

pub fn token(given: Option<&str>, file: Option<&Path>) -> anyhow::Result<Option<String>> {
    if let Some(t) = given {
        return Ok(Some(check_token(t, "--token")?));
    }
    let Some(file) = file else {
        return Ok(None);
    };
    let raw = strata_format::read_side_file(file)
        .with_context(|| format!("{}: cannot read the token file", file.display()))?;
    Ok(Some(check_token(
        &raw,
        &format!("the token file {}", file.display()),
    )?))
}
