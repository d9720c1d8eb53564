//! The byte-level lexer: one source line in, blocks of words out.
//!
//! The lexer knows each dialect's surface syntax (comments, block ends, `=AC()` forms) but
//! nothing of what the words mean. It never allocates on success: words go into a buffer
//! the caller reuses, and numbers are converted without building strings.

use crate::Dialect;

/// Word keys: 0..26 are the letters A..Z, the rest are multi-character addresses.
pub(crate) const K_CR: u8 = 26;
pub(crate) const K_TURN: u8 = 27;
pub(crate) const K_RP: u8 = 28;
pub(crate) const K_AP: u8 = 29;
pub(crate) const K_AT: u8 = 30;
pub(crate) const K_CARET: u8 = 31;
/// Number of distinct keys.
pub(crate) const N_KEYS: usize = 32;

/// The key of a letter word.
pub(crate) const fn key(letter: u8) -> u8 {
    letter - b'A'
}

/// How a value was written: plainly, or with an explicit absolute/incremental marker
/// (Sinumerik `=AC(..)`/`=IC(..)`, or a Heidenhain G90/G91 earlier in the same block).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Form {
    Plain,
    Abs,
    Inc,
}

/// One word of a block.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Word {
    pub key: u8,
    pub value: f64,
    /// 1-based byte column of the word's address.
    pub col: u32,
    pub form: Form,
}

/// What kind of block the lexer found besides its words.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct BlockFlags {
    /// The block starts with `/` (block delete): the control skips it.
    pub deleted: bool,
    /// The block holds a `%` program delimiter (a Heidenhain `%NAME G71 *` header or end,
    /// or a `%` line of the other dialects).
    pub percent: bool,
    /// LinuxCNC: the block holds a message comment (`(MSG,`, `(DEBUG,`, `(PRINT,`,
    /// `(LOG…`), which the language layer runs.
    pub message: bool,
}

/// True when the text after a `(` starts a LinuxCNC message comment: `MSG,`, `DEBUG,`,
/// `PRINT,` or `LOG…` (any case), spaces and tabs before it aside.
pub(crate) fn is_message_comment(after_paren: &[u8]) -> bool {
    let start = after_paren
        .iter()
        .position(|&b| b != b' ' && b != b'\t')
        .unwrap_or(after_paren.len());
    let rest = &after_paren[start..];
    [&b"msg,"[..], b"debug,", b"print,", b"log"]
        .iter()
        .any(|key| rest.len() >= key.len() && rest[..key.len()].eq_ignore_ascii_case(key))
}

/// An error in a block, from any stage (reading, the language layer, resolution): a
/// 1-based column and a message in the control manual's words. The interpreter turns it
/// into a [`crate::Diagnostic`] with the line and file.
#[derive(Debug)]
pub(crate) struct BlockError {
    pub col: u32,
    pub message: String,
}

fn err<T>(pos: usize, message: impl Into<String>) -> Result<T, BlockError> {
    Err(BlockError {
        col: col_of(pos),
        message: message.into(),
    })
}

/// Converts a byte offset into a 1-based column, saturating instead of overflowing.
pub(crate) fn col_of(pos: usize) -> u32 {
    u32::try_from(pos).unwrap_or(u32::MAX - 1).saturating_add(1)
}

/// Per-dialect lexical rules.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lexer {
    dialect: Dialect,
    /// The block delete switch: on, a block starting with `/` is skipped; off, the `/` is
    /// ignored and the block runs.
    block_delete: bool,
}

impl Lexer {
    pub(crate) fn new(dialect: Dialect) -> Self {
        Lexer {
            dialect,
            block_delete: true,
        }
    }

    /// The lexer with the block delete switch `on` or off.
    pub(crate) fn with_block_delete(self, on: bool) -> Self {
        Lexer {
            block_delete: on,
            ..self
        }
    }

    fn paren_comments(self) -> bool {
        matches!(
            self.dialect,
            Dialect::LinuxCnc | Dialect::Rockwell | Dialect::Fagor
        )
    }

    /// Lexes the next block of `line` starting at `*pos` into `words`.
    ///
    /// Returns `Ok(None)` when the line holds no further block. A block that only holds a
    /// comment comes back with no words.
    pub(crate) fn next_block(
        self,
        line: &[u8],
        pos: &mut usize,
        words: &mut Vec<Word>,
    ) -> Result<Option<BlockFlags>, BlockError> {
        words.clear();
        let mut flags = BlockFlags::default();
        let mut i = *pos;
        if i >= line.len() {
            return Ok(None);
        }
        loop {
            while i < line.len() && matches!(line[i], b' ' | b'\t' | b'\r') {
                i += 1;
            }
            let Some(&c) = line.get(i) else {
                *pos = i;
                return Ok(Some(flags));
            };
            match c {
                b'(' if self.paren_comments() => match line[i..].iter().position(|&b| b == b')') {
                    Some(off) => {
                        if self.dialect == Dialect::LinuxCnc && is_message_comment(&line[i + 1..]) {
                            flags.message = true;
                        }
                        i += off + 1;
                    }
                    None => return err(i, "unclosed comment: '(' without ')'"),
                },
                b'(' | b')' => {
                    return err(i, "arithmetic expressions are not supported yet");
                }
                b';' => {
                    if self.dialect == Dialect::Rockwell {
                        // Rockwell 9/Series: `;` is the end-of-block character, never a comment.
                        *pos = i + 1;
                        return Ok(Some(flags));
                    }
                    *pos = line.len();
                    return Ok(Some(flags));
                }
                b'*' if self.dialect == Dialect::Heidenhain => {
                    *pos = i + 1;
                    return Ok(Some(flags));
                }
                // LinuxCNC: only as the first character of the line, spaces aside (rs274:
                // "Bad character '/' used" after a comment or a word).
                b'/' if words.is_empty()
                    && !flags.deleted
                    && (self.dialect != Dialect::LinuxCnc
                        || line[..i].iter().all(|b| b.is_ascii_whitespace())) =>
                {
                    if !self.block_delete {
                        // The switch is off: the block runs as if the `/` were not there.
                        i += 1;
                        continue;
                    }
                    // Block delete: the whole block is skipped, so its words are not even
                    // checked (a deleted block may hold anything the control would ignore).
                    flags.deleted = true;
                    let end = self.block_end(line, i + 1);
                    *pos = end;
                    return Ok(Some(flags));
                }
                b'%' => {
                    flags.percent = true;
                    if self.dialect == Dialect::Heidenhain {
                        // `%NAME G71 *`: skip the program name, keep lexing the words after it.
                        i += 1;
                        while i < line.len() && !matches!(line[i], b' ' | b'\t' | b'*' | b'\r') {
                            i += 1;
                        }
                    } else {
                        // A `%` line (tape start/end, Fagor `%name` header, Sinumerik
                        // `%_N_NAME_MPF`) carries no words.
                        words.clear();
                        *pos = line.len();
                        return Ok(Some(flags));
                    }
                }
                b'#' => {
                    return match self.dialect {
                        Dialect::LinuxCnc | Dialect::Rockwell => {
                            err(i, "parameters (#) are not supported yet")
                        }
                        _ => err(i, "'#' instructions are not supported yet"),
                    };
                }
                b'[' => return err(i, "expressions ([...]) are not supported yet"),
                b'$' if self.dialect == Dialect::Sinumerik => {
                    // A system variable: `$A_OUT[1]=1` (a digital output), `$A_IN[2]` (an
                    // input), `$P_...`, ... Kerf's Sinumerik dialect has none of them.
                    let end = line[i + 1..]
                        .iter()
                        .position(|b| !(b.is_ascii_alphanumeric() || *b == b'_'))
                        .map_or(line.len(), |n| i + 1 + n);
                    let name = String::from_utf8_lossy(&line[i..end]).to_ascii_uppercase();
                    return err(i, format!("system variable {name} is not supported yet"));
                }
                b'$' => return err(i, "'$' control instructions are not supported yet"),
                b':' if self.dialect == Dialect::Sinumerik && words.is_empty() => {
                    // `:10` is a Sinumerik main block number; like N it carries no meaning here.
                    i += 1;
                    parse_number(line, &mut i, false)?;
                }
                b'@' | b'^' if self.dialect == Dialect::LinuxCnc => {
                    let k = if c == b'@' { K_AT } else { K_CARET };
                    let col = col_of(i);
                    i += 1;
                    let value = self.value(line, &mut i)?;
                    words.push(Word {
                        key: k,
                        value,
                        col,
                        form: Form::Plain,
                    });
                }
                _ if c.is_ascii_alphabetic() => {
                    if let Some(j) = self.plain_word(line, i, c, words) {
                        i = j;
                        continue;
                    }
                    if let Some(end) = self.letter_word(line, &mut i, c, words)? {
                        // A Rockwell program number: the rest of the line is skipped.
                        *pos = end;
                        return Ok(Some(flags));
                    }
                }
                _ => {
                    return err(i, format!("unexpected character '{}'", printable(c)));
                }
            }
        }
    }

    /// The overwhelmingly common `X-12.345` word: a letter `c` at `i` directly followed by
    /// a plain number and then a separator, pushed to `words`. Returns the offset after
    /// it, or `None` (nothing pushed) for any other word, which `letter_word` reads.
    #[inline(always)]
    fn plain_word(self, line: &[u8], i: usize, c: u8, words: &mut Vec<Word>) -> Option<usize> {
        let letter = c.to_ascii_uppercase();
        if letter == b'O' {
            return None;
        }
        let (value, j) = fast_number(line, i + 1)?;
        let plain_end = match line.get(j) {
            None | Some(b'(' | b';' | b'*' | b'\r') => true,
            // LinuxCNC ignores spaces, so `X1 0` is X10: let the general path look further.
            Some(b' ' | b'\t') => {
                self.dialect != Dialect::LinuxCnc
                    || !matches!(next_non_space(line, j), Some(b'0'..=b'9' | b'.'))
            }
            Some(c) => c.is_ascii_alphabetic(),
        };
        if !plain_end {
            return None;
        }
        words.push(Word {
            key: key(letter),
            value,
            col: col_of(i),
            form: Form::Plain,
        });
        Some(j)
    }

    /// A word that starts with the letter `c` at `*i` and is not a plain word (see
    /// `plain_word`), pushed to `words` (Sinumerik words by `sinumerik_word`). Returns the
    /// end of the block when the word ends it (a Rockwell program number `O1234` at the
    /// start of a block).
    fn letter_word(
        self,
        line: &[u8],
        i: &mut usize,
        c: u8,
        words: &mut Vec<Word>,
    ) -> Result<Option<usize>, BlockError> {
        if self.dialect == Dialect::Sinumerik {
            self.sinumerik_word(line, i, words)?;
        } else {
            let letter = c.to_ascii_uppercase();
            let col = col_of(*i);
            if letter == b'O' {
                match self.dialect {
                    Dialect::LinuxCnc => {
                        return err(*i, "O-words (subroutines and loops) are not supported yet");
                    }
                    Dialect::Rockwell if words.is_empty() => {
                        // A Fanuc-style program number `O1234` names the program;
                        // it carries no motion, so the rest of the line is skipped.
                        return Ok(Some(self.block_end(line, *i)));
                    }
                    _ => {}
                }
            }
            *i += 1;
            if self.dialect == Dialect::Fagor
                && line.get(*i).is_some_and(|b| b.is_ascii_alphabetic())
            {
                return err(
                    *i - 1,
                    "Fagor high-level instructions and variables are not supported yet",
                );
            }
            let value = self.value(line, i).map_err(|mut e| {
                if e.message == "bad number format" {
                    // Point at the word whose number is malformed.
                    e.col = col;
                    e.message = format!("bad number format after {}", letter as char);
                }
                e
            })?;
            if self.dialect == Dialect::Fagor
                && letter == b'P'
                && next_non_space(line, *i) == Some(b'=')
            {
                return err(*i, "arithmetic parameters (P) are not supported yet");
            }
            words.push(Word {
                key: key(letter),
                value,
                col,
                form: Form::Plain,
            });
        }
        Ok(None)
    }

    /// The offset just past the end of the block that contains `from`.
    fn block_end(self, line: &[u8], from: usize) -> usize {
        let sep = match self.dialect {
            Dialect::Rockwell => b';',
            Dialect::Heidenhain => b'*',
            _ => return line.len(),
        };
        match line
            .get(from..)
            .and_then(|rest| rest.iter().position(|&b| b == sep))
        {
            Some(off) => from + off + 1,
            None => line.len(),
        }
    }

    /// Parses the number after an address. LinuxCNC ignores spaces and tabs anywhere in a
    /// line, so `X 1 0.5` is `X10.5` there; the other dialects allow spaces only between
    /// the address and the number.
    fn value(self, line: &[u8], i: &mut usize) -> Result<f64, BlockError> {
        skip_spaces(line, i);
        match line.get(*i) {
            Some(b'#') if self.dialect == Dialect::LinuxCnc => {
                return err(*i, "parameters (#) are not supported yet");
            }
            Some(b'#') => return err(*i, "parameters are not supported yet"),
            Some(b'[') => return err(*i, "expressions ([...]) are not supported yet"),
            _ => {}
        }
        parse_number(line, i, self.dialect == Dialect::LinuxCnc)
    }

    /// Sinumerik words: `X10`, `X=10`, `X=AC(10)`, `X=IC(10)`, `CR=5`, `TURN=2`, `RP=..`,
    /// `AP=IC(..)`. R parameters and expressions are reported as not supported.
    fn sinumerik_word(
        self,
        line: &[u8],
        i: &mut usize,
        words: &mut Vec<Word>,
    ) -> Result<(), BlockError> {
        let start = *i;
        while *i < line.len() && (line[*i].is_ascii_alphabetic() || line[*i] == b'_') {
            *i += 1;
        }
        let ident = &line[start..*i];
        let k = if ident.len() == 1 {
            key(ident[0].to_ascii_uppercase())
        } else if ident.eq_ignore_ascii_case(b"CR") {
            K_CR
        } else if ident.eq_ignore_ascii_case(b"TURN") {
            K_TURN
        } else if ident.eq_ignore_ascii_case(b"RP") {
            K_RP
        } else if ident.eq_ignore_ascii_case(b"AP") {
            K_AP
        } else {
            let name = String::from_utf8_lossy(ident).to_ascii_uppercase();
            return err(start, format!("'{name}' is not supported"));
        };
        let col = col_of(start);
        let mut j = *i;
        skip_spaces(line, &mut j);
        let (value, form) = if line.get(j) == Some(&b'=') {
            j += 1;
            skip_spaces(line, &mut j);
            let rest = line.get(j..).unwrap_or(&[]);
            let form = if starts_with_ci(rest, b"AC") {
                Some(Form::Abs)
            } else if starts_with_ci(rest, b"IC") {
                Some(Form::Inc)
            } else {
                None
            };
            match form {
                Some(form) => {
                    j += 2;
                    skip_spaces(line, &mut j);
                    if line.get(j) != Some(&b'(') {
                        return err(j, "expected '(' after AC/IC");
                    }
                    j += 1;
                    skip_spaces(line, &mut j);
                    let v = sinumerik_number(line, &mut j)?;
                    skip_spaces(line, &mut j);
                    if line.get(j) != Some(&b')') {
                        return err(j, "arithmetic expressions are not supported yet");
                    }
                    j += 1;
                    (v, form)
                }
                None => (sinumerik_number(line, &mut j)?, Form::Plain),
            }
        } else {
            if k >= 26 {
                return err(j, "expected '=' after address");
            }
            (sinumerik_number(line, &mut j)?, Form::Plain)
        };
        // `R1=5` or `X1=..` would be an assignment: a parameter, not a word.
        if form == Form::Plain && line.get(j).is_some_and(|&b| b == b'=') {
            if k == key(b'R') {
                return err(start, "R parameters are not supported yet");
            }
            return err(start, "assignments are not supported yet");
        }
        if let Some(&b) = line.get(j)
            && matches!(b, b'+' | b'-' | b'*' | b'/' | b'(' | b'<' | b'>')
        {
            return err(j, "arithmetic expressions are not supported yet");
        }
        *i = j;
        words.push(Word {
            key: k,
            value,
            col,
            form,
        });
        Ok(())
    }
}

fn sinumerik_number(line: &[u8], i: &mut usize) -> Result<f64, BlockError> {
    match line.get(*i) {
        Some(b) if b.is_ascii_alphabetic() => {
            if b.eq_ignore_ascii_case(&b'R') {
                err(*i, "R parameters are not supported yet")
            } else {
                err(*i, "arithmetic expressions are not supported yet")
            }
        }
        Some(b'(') => err(*i, "arithmetic expressions are not supported yet"),
        _ => parse_number(line, i, false),
    }
}

fn starts_with_ci(s: &[u8], prefix: &[u8]) -> bool {
    s.len() >= prefix.len() && s[..prefix.len()].eq_ignore_ascii_case(prefix)
}

fn skip_spaces(line: &[u8], i: &mut usize) {
    while *i < line.len() && matches!(line[*i], b' ' | b'\t') {
        *i += 1;
    }
}

fn next_non_space(line: &[u8], mut i: usize) -> Option<u8> {
    skip_spaces(line, &mut i);
    line.get(i).copied()
}

fn printable(c: u8) -> String {
    if c.is_ascii_graphic() {
        (c as char).to_string()
    } else {
        format!("\\x{c:02x}")
    }
}

/// Parses `[+-]digits[.digits]` starting at `i` when it has at most 15 digits, returning
/// the value and the offset after it; `None` for anything else (the general path decides).
#[inline(always)]
fn fast_number(line: &[u8], i: usize) -> Option<(f64, usize)> {
    let rest = line.get(i..)?;
    let mut k = 0usize;
    let negative = match rest.first() {
        Some(b'-') => {
            k = 1;
            true
        }
        Some(b'+') => {
            k = 1;
            false
        }
        _ => false,
    };
    let mut mantissa: u64 = 0;
    let first_digit = k;
    while k < rest.len() {
        let d = rest[k].wrapping_sub(b'0');
        if d > 9 {
            break;
        }
        mantissa = mantissa * 10 + u64::from(d);
        k += 1;
        if k - first_digit > 15 {
            return None;
        }
    }
    let int_digits = k - first_digit;
    let mut frac = 0usize;
    if k < rest.len() && rest[k] == b'.' {
        k += 1;
        while k < rest.len() {
            let d = rest[k].wrapping_sub(b'0');
            if d > 9 {
                break;
            }
            mantissa = mantissa * 10 + u64::from(d);
            k += 1;
            frac += 1;
            if int_digits + frac > 15 {
                return None;
            }
        }
    }
    if int_digits + frac == 0 {
        return None;
    }
    let v = mantissa as f64 / POW10[frac];
    Some((if negative { -v } else { v }, i + k))
}

/// Exact powers of ten representable in an f64.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Parses `[+-]digits[.digits]` at `*i`. With `inner_spaces`, spaces and tabs between the
/// sign and digits are skipped (LinuxCNC semantics).
///
/// Up to 19 significant digits are exact in a `u64`; with at most 15 of them and at most
/// 22 fraction digits the quotient of two exact doubles is correctly rounded, which covers
/// every number a CAM post writes. Longer numbers are rounded slightly differently from
/// `str::parse`, far below any machine resolution.
pub(crate) fn parse_number(
    line: &[u8],
    i: &mut usize,
    inner_spaces: bool,
) -> Result<f64, BlockError> {
    if let Some(v) = parse_number_fast(line, i, inner_spaces) {
        return Ok(v);
    }
    parse_number_general(line, i, inner_spaces)
}

/// The common case: at most 19 digits and no embedded spaces. `None` sends the number to
/// the general parser, which handles (and reports) everything else.
#[inline]
fn parse_number_fast(line: &[u8], i: &mut usize, inner_spaces: bool) -> Option<f64> {
    let mut j = *i;
    let negative = match line.get(j) {
        Some(b'-') => {
            j += 1;
            true
        }
        Some(b'+') => {
            j += 1;
            false
        }
        _ => false,
    };
    let mut mantissa: u64 = 0;
    let mut digits = 0u32;
    while let Some(&c) = line.get(j) {
        if !c.is_ascii_digit() {
            break;
        }
        mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(c - b'0'));
        digits += 1;
        j += 1;
    }
    let mut frac = 0usize;
    if line.get(j) == Some(&b'.') {
        j += 1;
        while let Some(&c) = line.get(j) {
            if !c.is_ascii_digit() {
                break;
            }
            mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(c - b'0'));
            digits += 1;
            frac += 1;
            j += 1;
        }
    }
    if digits == 0 || digits > 15 || frac > 22 {
        return None;
    }
    if inner_spaces && matches!(line.get(j), Some(b' ' | b'\t')) {
        let mut k = j;
        skip_spaces(line, &mut k);
        if line
            .get(k)
            .is_some_and(|c| c.is_ascii_digit() || *c == b'.')
        {
            return None;
        }
    }
    *i = j;
    // Both operands are exact doubles, so the quotient is correctly rounded.
    let v = mantissa as f64 / POW10[frac];
    Some(if negative { -v } else { v })
}

fn parse_number_general(line: &[u8], i: &mut usize, inner_spaces: bool) -> Result<f64, BlockError> {
    // Collect sign, digits and point (without embedded spaces) into a stack buffer and let
    // the standard library round it correctly.
    let start = *i;
    let mut buf = [0u8; 128];
    let mut n = 0usize;
    let mut j = *i;
    let mut digits = 0usize;
    let mut seen_dot = false;
    let mut push = |c: u8, n: &mut usize| -> Result<(), BlockError> {
        match buf.get_mut(*n) {
            Some(slot) => {
                *slot = c;
                *n += 1;
                Ok(())
            }
            None => err(start, "number too long"),
        }
    };
    if let Some(&c) = line.get(j)
        && (c == b'+' || c == b'-')
    {
        push(c, &mut n)?;
        j += 1;
        if inner_spaces {
            skip_spaces(line, &mut j);
        }
    }
    while let Some(&c) = line.get(j) {
        if c.is_ascii_digit() {
            digits += 1;
            push(c, &mut n)?;
            j += 1;
        } else if c == b'.' && !seen_dot {
            seen_dot = true;
            push(c, &mut n)?;
            j += 1;
        } else if inner_spaces && (c == b' ' || c == b'\t') {
            let mut k = j;
            skip_spaces(line, &mut k);
            match line.get(k) {
                Some(d) if d.is_ascii_digit() || (*d == b'.' && !seen_dot) => j = k,
                _ => break,
            }
        } else {
            break;
        }
    }
    if digits == 0 {
        return err(start, "bad number format");
    }
    let text = std::str::from_utf8(&buf[..n]).unwrap_or("");
    let v: f64 = match text.parse() {
        Ok(v) => v,
        Err(_) => return err(start, "bad number format"),
    };
    if !v.is_finite() {
        return err(start, "number out of range");
    }
    *i = j;
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn num(s: &str, spaces: bool) -> Option<f64> {
        let mut i = 0;
        parse_number(s.as_bytes(), &mut i, spaces).ok()
    }

    #[test]
    fn numbers_in_every_written_form() {
        assert_eq!(num("-.5", false), Some(-0.5));
        assert_eq!(num("+5", false), Some(5.0));
        assert_eq!(num("1.", false), Some(1.0));
        assert_eq!(num("0.1", false), Some(0.1));
        assert_eq!(num("123.456", false), Some(123.456));
        assert_eq!(num("1 0.5", true), Some(10.5));
        assert_eq!(num("- 2", true), Some(-2.0));
        assert_eq!(num(".", false), None);
        assert_eq!(num("-", false), None);
        assert_eq!(num("", false), None);
        assert_eq!(num("4294967295", false), Some(4294967295.0));
        let long = "1".repeat(100);
        assert_eq!(num(&long, false), Some(long.parse().unwrap()));
        assert!(num(&"1".repeat(400), false).is_none(), "too long");
        assert_eq!(num("0.00000000000000000000000000001", false), Some(1e-29));
    }

    #[test]
    fn numbers_match_std_parse_for_typical_posts() {
        for s in [
            "12.3456",
            "0.0001",
            "-99999.9999",
            "3.14159265358979",
            "25.4",
        ] {
            let expect: f64 = s.parse().unwrap();
            assert_eq!(num(s, false), Some(expect), "{s}");
        }
    }

    type Blocks = Vec<Vec<(u8, f64, u32)>>;

    fn lex_all(d: Dialect, s: &str) -> Result<Blocks, String> {
        let lx = Lexer::new(d);
        let mut pos = 0;
        let mut words = Vec::new();
        let mut out = Vec::new();
        loop {
            match lx.next_block(s.as_bytes(), &mut pos, &mut words) {
                Ok(Some(_)) => out.push(words.iter().map(|w| (w.key, w.value, w.col)).collect()),
                Ok(None) => return Ok(out),
                Err(e) => return Err(format!("{}: {}", e.col, e.message)),
            }
        }
    }

    #[test]
    fn rockwell_semicolon_ends_a_block() {
        let blocks = lex_all(Dialect::Rockwell, "G01 X1 ; Y2 (c;omment) ;").unwrap();
        assert_eq!(blocks.len(), 2);
        assert_eq!(blocks[1], vec![(key(b'Y'), 2.0, 10)]);
    }

    #[test]
    fn linuxcnc_comments_and_spans() {
        let blocks = lex_all(Dialect::LinuxCnc, "g1 (move) x-.5 ; rest").unwrap();
        assert_eq!(
            blocks,
            vec![vec![(key(b'G'), 1.0, 1), (key(b'X'), -0.5, 11)]]
        );
        assert!(
            lex_all(Dialect::LinuxCnc, "G1 X#1")
                .unwrap_err()
                .contains("parameters (#)")
        );
        assert!(
            lex_all(Dialect::LinuxCnc, "G1 (open")
                .unwrap_err()
                .starts_with("4:")
        );
    }

    #[test]
    fn sinumerik_forms() {
        let lx = Lexer::new(Dialect::Sinumerik);
        let mut pos = 0;
        let mut words = Vec::new();
        let line = b"G2 X=AC(10) I=IC(-5) CR=-7.5 TURN=2 AP=IC(30) RP=10";
        lx.next_block(line, &mut pos, &mut words).unwrap();
        let forms: Vec<_> = words.iter().map(|w| (w.key, w.value, w.form)).collect();
        assert_eq!(
            forms,
            vec![
                (key(b'G'), 2.0, Form::Plain),
                (key(b'X'), 10.0, Form::Abs),
                (key(b'I'), -5.0, Form::Inc),
                (K_CR, -7.5, Form::Plain),
                (K_TURN, 2.0, Form::Plain),
                (K_AP, 30.0, Form::Inc),
                (K_RP, 10.0, Form::Plain),
            ]
        );
        assert!(
            lex_all(Dialect::Sinumerik, "R1=5")
                .unwrap_err()
                .contains("R parameters")
        );
        assert!(
            lex_all(Dialect::Sinumerik, "X=R1")
                .unwrap_err()
                .contains("R parameters")
        );
        assert!(
            lex_all(Dialect::Sinumerik, "X=10+5")
                .unwrap_err()
                .contains("expressions")
        );
        assert!(
            lex_all(Dialect::Sinumerik, "TRANS X10")
                .unwrap_err()
                .contains("'TRANS'")
        );
    }

    #[test]
    fn heidenhain_star_and_header() {
        let blocks = lex_all(Dialect::Heidenhain, "%PART G71 *").unwrap();
        assert_eq!(blocks, vec![vec![(key(b'G'), 71.0, 7)]]);
        let blocks = lex_all(Dialect::Heidenhain, "N10 G01 X+10 * ; note").unwrap();
        assert_eq!(blocks.len(), 2);
        assert!(blocks[1].is_empty());
    }

    #[test]
    fn block_delete_skips_words() {
        let blocks = lex_all(Dialect::LinuxCnc, "/G1 X#5").unwrap();
        assert_eq!(blocks, vec![vec![]]);
    }

    #[test]
    fn block_delete_off_runs_the_block() {
        let lx = Lexer::new(Dialect::LinuxCnc).with_block_delete(false);
        let mut words = Vec::new();
        let mut pos = 0;
        let flags = lx.next_block(b" /G1 X5", &mut pos, &mut words).unwrap();
        assert!(!flags.expect("a block").deleted);
        let got: Vec<(u8, f64, u32)> = words.iter().map(|w| (w.key, w.value, w.col)).collect();
        assert_eq!(got, vec![(key(b'G'), 1.0, 3), (key(b'X'), 5.0, 6)]);
        // The `/` is still only allowed first on a LinuxCNC line.
        let mut pos = 0;
        assert!(lx.next_block(b"G1 /X5", &mut pos, &mut words).is_err());
    }
}
