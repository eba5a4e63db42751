//! Text PLY elements after the vertices, read through to check the body: whitespace-separated
//! numbers, however they are spread over lines (blank lines, or several faces on one line, are
//! text PLY too): each scalar property one number, each list its count and that many.

use super::ply_header::{ElementDef, shown};
use std::fs::File;
use std::io::{BufRead, BufReader, Read};

/// Reads `elements` from `body` (`left` bytes of the file unread), then what follows them must
/// be white space. The error is the fault, in words, without the file name.
pub fn skip_text_elements(
    body: &mut BufReader<File>,
    elements: &[ElementDef],
    left: &mut u64,
) -> Result<(), String> {
    let mut words = Words::default();
    for el in elements {
        let name = shown(&el.name);
        for i in 0..el.count {
            for p in &el.properties {
                let ends = || format!("the file ends inside element \"{name}\" (item {i})");
                let Some(first) = words.next(body, left)? else {
                    return Err(ends());
                };
                let count = match p.list {
                    None => 0,
                    Some(_) => words.line[first.clone()].parse::<u64>().map_err(|_| {
                        format!(
                            "element \"{name}\" item {i}: list \"{}\" has an item count \"{}\" that is not a whole number",
                            shown(&p.name),
                            shown(&words.line[first.clone()])
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
    if words.next(body, left)?.is_some() || *left > 0 && !only_space(body, left) {
        let last = elements.last().map_or(String::new(), |e| shown(&e.name));
        return Err(format!(
            "text follows the last item of element \"{last}\", the header's last element (is its count in the header right?)"
        ));
    }
    Ok(())
}

/// The words of the text, a line at a time.
#[derive(Default)]
struct Words {
    line: String,
    at: usize,
}

impl Words {
    /// Where the next word lies in `self.line`; `None` at the end of the file.
    fn next(
        &mut self,
        body: &mut BufReader<File>,
        left: &mut u64,
    ) -> Result<Option<std::ops::Range<usize>>, String> {
        loop {
            let rest = &self.line[self.at..];
            let start = rest.len() - rest.trim_start().len();
            if start < rest.len() {
                let word = &rest[start..];
                let len = word.find(|c: char| c.is_whitespace()).unwrap_or(word.len());
                let from = self.at + start;
                self.at = from + len;
                return Ok(Some(from..from + len));
            }
            self.line.clear();
            self.at = 0;
            let got = body.take(*left).read_line(&mut self.line).map_err(|e| {
                format!("cannot read the elements after the vertices ({})", e.kind())
            })?;
            if got == 0 {
                return Ok(None);
            }
            *left -= got as u64;
        }
    }
}

/// Whether the rest of the body (`left` bytes) is white space.
fn only_space(body: &mut BufReader<File>, left: &mut u64) -> bool {
    let mut rest = Vec::new();
    let _ = body.take(*left).read_to_end(&mut rest);
    *left = 0;
    rest.iter().all(|b| b.is_ascii_whitespace() || *b == 0)
}
