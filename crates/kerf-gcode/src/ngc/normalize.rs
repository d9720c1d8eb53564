//! Line normalisation as LinuxCNC reads a line (spaces out, letters lower case, comments
//! kept, columns mapped back to the source) and the head of an O-word line (its label and
//! keyword).

use std::sync::Arc;

use super::*;

/// Normalizes a line as LinuxCNC reads it: spaces and tabs outside comments removed,
/// letters lower case outside comments, a `;` comment dropped; `cols` maps each kept byte
/// to its 1-based source column.
pub(super) fn normalize(
    line: &[u8],
    norm: &mut Vec<u8>,
    cols: &mut Vec<u32>,
) -> Result<(), BlockError> {
    norm.clear();
    cols.clear();
    let mut i = 0;
    while i < line.len() {
        let c = line[i];
        match c {
            b' ' | b'\t' | b'\r' => {}
            b';' => break,
            b'(' => {
                let Some(off) = line[i..].iter().position(|&b| b == b')') else {
                    return fail(crate::lex::col_of(i), "Unclosed comment found");
                };
                for (k, &b) in line[i..=i + off].iter().enumerate() {
                    norm.push(b);
                    cols.push(crate::lex::col_of(i + k));
                }
                i += off;
            }
            _ => {
                norm.push(c.to_ascii_lowercase());
                cols.push(crate::lex::col_of(i));
            }
        }
        i += 1;
    }
    Ok(())
}

/// The O-word of a normalized line: label, keyword and the offset after the keyword.
/// `Ok(None)` when the line holds no O-word. Leading `N` words and a block delete are
/// skipped.
pub(super) fn o_head(
    norm: &[u8],
    cols: &[u32],
) -> Result<Option<(Arc<str>, Kw, usize)>, BlockError> {
    let mut i = 0;
    if norm.first() == Some(&b'/') {
        return Ok(None);
    }
    if norm.first() == Some(&b'n') {
        i = 1;
        while norm
            .get(i)
            .is_some_and(|c| c.is_ascii_digit() || *c == b'.')
        {
            i += 1;
        }
    }
    if norm.get(i) != Some(&b'o') {
        return Ok(None);
    }
    let col = cols.get(i).copied().unwrap_or(1);
    i += 1;
    let label: String = match norm.get(i) {
        Some(b'<') => {
            let start = i + 1;
            let Some(off) = norm[start..].iter().position(|&b| b == b'>') else {
                return fail(col, "Named parameter not terminated");
            };
            i = start + off + 1;
            if off == 0 {
                return fail(col, "Bad O-word label");
            }
            String::from_utf8_lossy(&norm[start..start + off]).into_owned()
        }
        Some(c) if c.is_ascii_digit() => {
            let start = i;
            while norm.get(i).is_some_and(|c| c.is_ascii_digit()) {
                i += 1;
            }
            let digits = &norm[start..i];
            let trimmed: &[u8] = match digits.iter().position(|&b| b != b'0') {
                Some(p) => &digits[p..],
                None => b"0",
            };
            if trimmed.len() > 18 {
                return fail(col, "O-word number too large");
            }
            String::from_utf8_lossy(trimmed).into_owned()
        }
        Some(b'[') => {
            // A computed label (`o[#1] call`): kept as written and evaluated when the line
            // runs (in `Ngc::line`).
            let start = i;
            let closed;
            (i, closed) = skip_brackets(norm, i);
            if !closed {
                return fail(col, "Unclosed expression");
            }
            String::from_utf8_lossy(&norm[start..i]).into_owned()
        }
        _ => return fail(col, "Bad O-word label"),
    };
    for (text, kw) in KEYWORDS {
        if norm.get(i..).is_some_and(|r| r.starts_with(text)) {
            return Ok(Some((Arc::from(label), kw, i + text.len())));
        }
    }
    fail(
        cols.get(i).copied().unwrap_or(col),
        "Unknown command in O-word",
    )
}

/// From the `[` at `i`, the index after its matching `]`, and whether it was found (the
/// end of the line otherwise).
pub(super) fn skip_brackets(norm: &[u8], mut i: usize) -> (usize, bool) {
    let mut depth = 0usize;
    while let Some(&c) = norm.get(i) {
        i += 1;
        match c {
            b'[' => depth += 1,
            b']' => {
                depth = depth.saturating_sub(1);
                if depth == 0 {
                    return (i, true);
                }
            }
            _ => {}
        }
    }
    (i, false)
}

/// Checks what follows an O-word's keyword: its bracketed values (none for most keywords,
/// one for `if`/`elseif`/`while`/`repeat`/`return`/`endsub`, any number for `call`), then
/// only comments. Anything else is LinuxCNC's "Unexpected character after O-word": an
/// O-word line runs nothing else, so nothing may be silently dropped.
pub(super) fn check_o_tail(
    norm: &[u8],
    cols: &[u32],
    after: usize,
    kw: Kw,
) -> Result<(), BlockError> {
    let max_groups = match kw {
        Kw::Call => usize::MAX,
        Kw::If | Kw::ElseIf | Kw::While | Kw::Repeat | Kw::Return | Kw::EndSub => 1,
        _ => 0,
    };
    let mut i = after;
    let mut groups = 0;
    while groups < max_groups && norm.get(i) == Some(&b'[') {
        i = skip_brackets(norm, i).0;
        groups += 1;
    }
    while let Some(&c) = norm.get(i) {
        if c != b'(' {
            let col = cols.get(i).copied().unwrap_or(1);
            return fail(col, "Unexpected character after O-word");
        }
        match norm[i..].iter().position(|&b| b == b')') {
            Some(off) => i += off + 1,
            None => break,
        }
    }
    Ok(())
}
