//! Text PLY elements after the vertices, read through to check the body: whitespace-separated
//! numbers, however they are spread over lines (blank lines, or several faces on one line, are
//! text PLY too): each scalar property one number, each list its count and that many.

use super::ply_header::{ElementDef, shown};
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use strata_format::AttrType;

/// Reads `elements` from `body` (`left` bytes of the file unread); what follows them must be
/// white space. The error is the fault, in words, without the file name.
pub fn skip_text_elements(
    body: &mut BufReader<File>,
    elements: &[ElementDef],
    left: &mut u64,
) -> Result<(), String> {
    let mut words = Words::default();
    for el in elements {
        let name = shown(&el.name);
        for i in 0..el.count {
            let ends =
                || format!("the file ends inside element \"{name}\" (item {i}, counting from 0)");
            for p in &el.properties {
                let Some(word) = words.next(body, left)? else {
                    return Err(ends());
                };
                let count = match p.list {
                    None => 0,
                    Some(ty) => list_count(&words.line[word], ty).map_err(|fault| {
                        format!(
                            "element \"{name}\" item {i} (counting from 0): list \"{}\" has {fault}",
                            shown(&p.name)
                        )
                    })?,
                };
                for _ in 0..count {
                    if words.next(body, left)?.is_none() {
                        return Err(ends());
                    }
                }
            }
        }
    }
    if words.next(body, left)?.is_some() {
        let last = elements.last().map_or(String::new(), |e| shown(&e.name));
        return Err(format!(
            "text follows the last item of element \"{last}\", the header's last element (is its count in the header right?)"
        ));
    }
    Ok(())
}

/// A list's item count from its word: a whole number its count type holds.
fn list_count(word: &[u8], ty: AttrType) -> Result<u64, String> {
    let text = String::from_utf8_lossy(word);
    let n: i128 = text.parse().map_err(|_| {
        format!(
            "an item count \"{}\" that is not a whole number",
            shown(&text)
        )
    })?;
    let max: i128 = match ty {
        AttrType::I8 => i8::MAX.into(),
        AttrType::U8 => u8::MAX.into(),
        AttrType::I16 => i16::MAX.into(),
        AttrType::U16 => u16::MAX.into(),
        AttrType::I32 => i32::MAX.into(),
        AttrType::U32 => u32::MAX.into(),
        _ => u64::MAX.into(),
    };
    if n < 0 || n > max {
        return Err(format!(
            "an item count {n} that its count type, {}, cannot give (0 to {max})",
            ty.name()
        ));
    }
    Ok(n as u64)
}

/// The words of the text, a line at a time, as bytes (text PLY need not be UTF-8 where it is
/// only skipped); NUL counts as white space, as padding after the body does.
#[derive(Default)]
struct Words {
    line: Vec<u8>,
    at: usize,
}

impl Words {
    /// Where the next word lies in `self.line`; `None` at the end of the file.
    fn next(
        &mut self,
        body: &mut BufReader<File>,
        left: &mut u64,
    ) -> Result<Option<std::ops::Range<usize>>, String> {
        let space = |b: &u8| b.is_ascii_whitespace() || *b == 0;
        loop {
            let rest = &self.line[self.at..];
            if let Some(start) = rest.iter().position(|b| !space(b)) {
                let len = rest[start..]
                    .iter()
                    .position(space)
                    .unwrap_or(rest.len() - start);
                let from = self.at + start;
                self.at = from + len;
                return Ok(Some(from..from + len));
            }
            self.line.clear();
            self.at = 0;
            let got = body
                .take(*left)
                .read_until(b'\n', &mut self.line)
                .map_err(|e| {
                    format!("cannot read the elements after the vertices ({})", e.kind())
                })?;
            if got == 0 {
                return Ok(None);
            }
            *left -= got as u64;
        }
    }
}
