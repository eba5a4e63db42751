//! The bearer token: what may serve as one, and checking a request's `Authorization` header.

use crate::ServerError;

/// A token as given on the command line or read from a file (`origin` says which, for the
/// message): surrounding whitespace (a file's newline) is dropped; an empty token, or one with
/// whitespace or control characters inside, is refused, since it would either let everyone in
/// or never match a header.
pub fn check_token(raw: &str, origin: &str) -> Result<String, ServerError> {
    let token = raw.trim();
    if token.is_empty() {
        return Err(ServerError::Token(format!(
            "{origin} is empty or blank, which would serve everything to anyone: give a \
             non-empty token or no token option at all"
        )));
    }
    if token.chars().any(|c| c.is_whitespace() || c.is_control()) {
        return Err(ServerError::Token(format!(
            "{origin} holds whitespace or control characters, which no Authorization header \
             can carry: use a token of visible characters"
        )));
    }
    Ok(token.to_string())
}

/// Whether `header` (an `Authorization` value) carries `token` with the `Bearer` scheme, whose
/// name is case-insensitive (RFC 9110 §11.1).
pub fn bearer_matches(header: Option<&[u8]>, token: &str) -> bool {
    let Some(value) = header else {
        return false;
    };
    let Some(space) = value.iter().position(|&b| b == b' ') else {
        return false;
    };
    let (scheme, given) = value.split_at(space);
    if !scheme.eq_ignore_ascii_case(b"bearer") {
        return false;
    }
    let given = given.trim_ascii();
    // Constant time in the token's length: no early exit on the first differing byte.
    let token = token.as_bytes();
    given.len() == token.len()
        && given
            .iter()
            .zip(token)
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scheme_is_case_insensitive_and_the_token_exact() {
        for ok in [
            "Bearer s3cret",
            "bearer s3cret",
            "BEARER  s3cret ",
            "BeArEr s3cret",
        ] {
            assert!(bearer_matches(Some(ok.as_bytes()), "s3cret"), "{ok}");
        }
        for bad in [
            "Bearer s3cre",
            "Bearer S3CRET",
            "Basic s3cret",
            "Bearers3cret",
            "s3cret",
            "",
        ] {
            assert!(!bearer_matches(Some(bad.as_bytes()), "s3cret"), "{bad}");
        }
        assert!(!bearer_matches(None, "s3cret"));
    }

    #[test]
    fn empty_blank_and_spaced_tokens_are_refused() {
        for bad in ["", "   ", "\n", "a b", "a\tb"] {
            assert!(check_token(bad, "--token").is_err(), "{bad:?}");
        }
        assert_eq!(check_token("s3cret\n", "x").ok().as_deref(), Some("s3cret"));
    }
}
