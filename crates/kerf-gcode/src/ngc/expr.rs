//! LinuxCNC real values: numbers, `[expressions]`, parameters `#n`, `##n`, `#<name>`, unary
//! functions and unary minus/plus, read from a normalized line (spaces removed, letters
//! lower case outside comments).

use super::{BlockError, fail};

/// Values are equal for EQ/NE when they differ by less than this (LinuxCNC's
/// TOLERANCE_EQUAL, manual 11.4.7).
const TOLERANCE_EQUAL: f64 = 0.0001;

/// The deepest nesting of brackets and parameter references in one value: deeper input is
/// refused instead of overflowing the stack.
const MAX_DEPTH: u32 = 64;

/// Where values of parameters come from.
pub(crate) trait Params {
    /// `#n`: the value, or an error in LinuxCNC's words.
    fn numbered(&self, n: f64, col: u32) -> Result<f64, BlockError>;
    /// `#<name>` (name lower case, spaces removed).
    fn named(&self, name: &str, col: u32) -> Result<f64, BlockError>;
    /// `EXISTS[#n]`: whether `#n` can be read, without reading it (reading `#5399` may
    /// wait for the machine).
    fn numbered_exists(&self, n: f64, col: u32) -> bool {
        self.numbered(n, col).is_ok()
    }
    /// `EXISTS[#<name>]`.
    fn exists(&self, name: &str) -> bool;
}

/// A reader over one normalized line.
pub(crate) struct Reader<'a> {
    pub bytes: &'a [u8],
    pub cols: &'a [u32],
    pub pos: usize,
    depth: u32,
}

#[derive(Clone, Copy, PartialEq)]
enum Op {
    Pow,
    Mul,
    Div,
    Mod,
    Add,
    Sub,
    Eq,
    Ne,
    Gt,
    Ge,
    Lt,
    Le,
    And,
    Or,
    Xor,
}

impl Op {
    fn precedence(self) -> u8 {
        match self {
            Op::Pow => 5,
            Op::Mul | Op::Div | Op::Mod => 4,
            Op::Add | Op::Sub => 3,
            Op::Eq | Op::Ne | Op::Gt | Op::Ge | Op::Lt | Op::Le => 2,
            Op::And | Op::Or | Op::Xor => 1,
        }
    }
}

impl<'a> Reader<'a> {
    pub(crate) fn new(bytes: &'a [u8], cols: &'a [u32], pos: usize) -> Self {
        Reader {
            bytes,
            cols,
            pos,
            depth: 0,
        }
    }

    /// The source column of byte `i` of the normalized line.
    pub(crate) fn col_at(&self, i: usize) -> u32 {
        self.cols.get(i).or(self.cols.last()).copied().unwrap_or(1)
    }

    pub(crate) fn col(&self) -> u32 {
        self.col_at(self.pos)
    }

    pub(crate) fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    fn starts_with(&self, s: &[u8]) -> bool {
        self.bytes
            .get(self.pos..)
            .is_some_and(|rest| rest.starts_with(s))
    }

    /// A real value: number, `[expr]`, parameter, unary function, or one of these after a
    /// unary minus or plus.
    pub(crate) fn real_value(&mut self, p: &dyn Params) -> Result<f64, BlockError> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return fail(self.col(), "expression nested too deeply");
        }
        let v = self.real_value_inner(p);
        self.depth -= 1;
        v
    }

    fn real_value_inner(&mut self, p: &dyn Params) -> Result<f64, BlockError> {
        let col = self.col();
        match self.peek() {
            Some(b'[') => self.expression(p),
            Some(b'#') => self.parameter(p),
            Some(b'-') => {
                self.pos += 1;
                Ok(-self.real_value(p)?)
            }
            Some(b'+') => {
                self.pos += 1;
                self.real_value(p)
            }
            Some(c) if c.is_ascii_digit() || c == b'.' => self.number(),
            Some(c) if c.is_ascii_alphabetic() => self.unary(p),
            None => fail(col, "Missing value at end of line"),
            Some(_) => fail(col, "Bad number format"),
        }
    }

    fn number(&mut self) -> Result<f64, BlockError> {
        let start = self.pos;
        let mut dot = false;
        let mut digits = 0;
        while let Some(c) = self.peek() {
            if c.is_ascii_digit() {
                digits += 1;
            } else if c == b'.' && !dot {
                dot = true;
            } else {
                break;
            }
            self.pos += 1;
        }
        let text = std::str::from_utf8(&self.bytes[start..self.pos]).unwrap_or("");
        if digits == 0 || (self.peek() == Some(b'.')) {
            return fail(self.col_at(start), "Bad number format");
        }
        match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => fail(self.col_at(start), "Bad number format"),
        }
    }

    /// `#n`, `##n`, `#[expr]`, `#<name>`.
    fn parameter(&mut self, p: &dyn Params) -> Result<f64, BlockError> {
        let col = self.col();
        self.pos += 1; // '#'
        if self.peek() == Some(b'<') {
            let name = self.name()?;
            return p.named(&name, col);
        }
        let n = self.real_value(p)?;
        p.numbered(n, col)
    }

    /// `<name>` after a `#`: the name, lower case without spaces (already normalized).
    pub(crate) fn name(&mut self) -> Result<String, BlockError> {
        let col = self.col();
        self.pos += 1; // '<'
        let start = self.pos;
        while let Some(c) = self.peek() {
            if c == b'>' {
                let name = String::from_utf8_lossy(&self.bytes[start..self.pos]).into_owned();
                self.pos += 1;
                if name.is_empty() {
                    return fail(col, "Named parameter not terminated");
                }
                return Ok(name);
            }
            self.pos += 1;
        }
        fail(col, "Named parameter not terminated")
    }

    /// `[` expression `]`.
    pub(crate) fn expression(&mut self, p: &dyn Params) -> Result<f64, BlockError> {
        self.pos += 1; // '['
        let mut values: Vec<f64> = Vec::with_capacity(4);
        let mut ops: Vec<(Op, u32)> = Vec::with_capacity(4);
        values.push(self.real_value(p)?);
        loop {
            let col = self.col();
            if self.peek() == Some(b']') {
                self.pos += 1;
                break;
            }
            let op = self.operator()?;
            while let Some(&(top, top_col)) = ops.last() {
                if top.precedence() >= op.precedence() {
                    ops.pop();
                    reduce(&mut values, top, top_col)?;
                } else {
                    break;
                }
            }
            ops.push((op, col));
            values.push(self.real_value(p)?);
        }
        let col = self.col();
        while let Some((op, op_col)) = ops.pop() {
            reduce(&mut values, op, op_col)?;
        }
        values
            .pop()
            .map_or_else(|| fail(col, "Unknown operation"), Ok)
    }

    fn operator(&mut self) -> Result<Op, BlockError> {
        let col = self.col();
        let table: [(&[u8], Op); 15] = [
            (b"**", Op::Pow),
            (b"*", Op::Mul),
            (b"/", Op::Div),
            (b"mod", Op::Mod),
            (b"+", Op::Add),
            (b"-", Op::Sub),
            (b"eq", Op::Eq),
            (b"ne", Op::Ne),
            (b"gt", Op::Gt),
            (b"ge", Op::Ge),
            (b"lt", Op::Lt),
            (b"le", Op::Le),
            (b"and", Op::And),
            (b"or", Op::Or),
            (b"xor", Op::Xor),
        ];
        for (text, op) in table {
            if self.starts_with(text) {
                self.pos += text.len();
                return Ok(op);
            }
        }
        fail(col, "Unknown operation")
    }

    /// A unary function: `name[expr]`, `atan[a]/[b]`, `exists[#<name>]`.
    fn unary(&mut self, p: &dyn Params) -> Result<f64, BlockError> {
        let col = self.col();
        let start = self.pos;
        while self.peek().is_some_and(|c| c.is_ascii_alphabetic()) {
            self.pos += 1;
        }
        let name = &self.bytes[start..self.pos];
        if self.peek() != Some(b'[') {
            return fail(col, "Unknown word starting with letter");
        }
        if name == b"exists" {
            self.pos += 1;
            if self.peek() != Some(b'#') {
                return fail(self.col(), "Named parameter expected after EXISTS");
            }
            let exists = if self.starts_with(b"#<") {
                self.pos += 1;
                let n = self.name()?;
                p.exists(&n)
            } else {
                // A numbered parameter exists when its number is in range (rs274 reads
                // EXISTS[#1] as 1).
                let col = self.col();
                self.pos += 1;
                let n = self.real_value(p)?;
                p.numbered_exists(n, col)
            };
            if self.peek() != Some(b']') {
                return fail(self.col(), "Unknown operation");
            }
            self.pos += 1;
            return Ok(if exists { 1.0 } else { 0.0 });
        }
        let f: fn(f64) -> Result<f64, &'static str> = match name {
            b"abs" => |x| Ok(x.abs()),
            b"acos" => |x| {
                if (-1.0..=1.0).contains(&x) {
                    Ok(x.acos().to_degrees())
                } else {
                    Err("Argument to acos out of range")
                }
            },
            b"asin" => |x| {
                if (-1.0..=1.0).contains(&x) {
                    Ok(x.asin().to_degrees())
                } else {
                    Err("Argument to asin out of range")
                }
            },
            b"cos" => |x| Ok(x.to_radians().cos()),
            b"sin" => |x| Ok(x.to_radians().sin()),
            b"tan" => |x| Ok(x.to_radians().tan()),
            b"exp" => |x| Ok(x.exp()),
            b"fix" => |x| Ok(x.floor()),
            b"fup" => |x| Ok(x.ceil()),
            b"round" => |x| Ok(x.round()),
            b"ln" => |x| {
                if x > 0.0 {
                    Ok(x.ln())
                } else {
                    Err("Zero or negative argument to ln")
                }
            },
            b"sqrt" => |x| {
                if x >= 0.0 {
                    Ok(x.sqrt())
                } else {
                    Err("Negative argument to sqrt")
                }
            },
            b"atan" => {
                let a = self.expression(p)?;
                if self.peek() != Some(b'/') {
                    return fail(self.col(), "Slash missing after first ATAN argument");
                }
                self.pos += 1;
                if self.peek() != Some(b'[') {
                    return fail(self.col(), "Left bracket missing after slash with ATAN");
                }
                let b = self.expression(p)?;
                return Ok(a.atan2(b).to_degrees());
            }
            _ => return fail(col, "Unknown word starting with letter"),
        };
        let x = self.expression(p)?;
        let v = f(x).or_else(|m| fail(col, m))?;
        finite(v, col)
    }
}

fn finite(v: f64, col: u32) -> Result<f64, BlockError> {
    if v.is_finite() {
        Ok(v)
    } else {
        fail(col, "Result of expression out of range")
    }
}

fn reduce(values: &mut Vec<f64>, op: Op, col: u32) -> Result<(), BlockError> {
    let (Some(b), Some(a)) = (values.pop(), values.pop()) else {
        return fail(col, "Unknown operation");
    };
    let t = |c: bool| if c { 1.0 } else { 0.0 };
    let v = match op {
        Op::Pow => {
            if a < 0.0 && b.fract() != 0.0 {
                return fail(col, "Attempt to raise negative to non integer power");
            }
            a.powf(b)
        }
        Op::Mul => a * b,
        Op::Div => {
            if b == 0.0 {
                return fail(col, "Attempt to divide by zero");
            }
            a / b
        }
        Op::Mod => {
            if b == 0.0 {
                return fail(col, "Attempt to divide by zero");
            }
            let r = a % b;
            // LinuxCNC's MOD: the result is made non-negative (-7 MOD 3 is 2).
            if r < 0.0 { r + b.abs() } else { r }
        }
        Op::Add => a + b,
        Op::Sub => a - b,
        Op::Eq => t((a - b).abs() < TOLERANCE_EQUAL),
        Op::Ne => t((a - b).abs() >= TOLERANCE_EQUAL),
        Op::Gt => t(a > b),
        Op::Ge => t(a >= b),
        Op::Lt => t(a < b),
        Op::Le => t(a <= b),
        Op::And => t(a != 0.0 && b != 0.0),
        Op::Or => t(a != 0.0 || b != 0.0),
        Op::Xor => t((a != 0.0) != (b != 0.0)),
    };
    values.push(finite(v, col)?);
    Ok(())
}
