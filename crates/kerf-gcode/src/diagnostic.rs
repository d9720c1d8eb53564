//! The error the interpreter reports: a message at a place in the source, with the
//! subroutine calls that led there.

/// An error at a place in the source: the CLI prints `FILE:LINE:COL: error: MESSAGE`.
///
/// An error inside a LinuxCNC subroutine file names that file in [`Diagnostic::file`] and
/// the calls that led there in [`Diagnostic::called_from`]; [`Diagnostic::render`] writes
/// the whole report.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{line}:{col}: error: {message}")]
pub struct Diagnostic {
    /// 1-based source line.
    pub line: u32,
    /// 1-based column, in bytes.
    pub col: u32,
    /// What is wrong, in the words of the control's manual.
    pub message: String,
    /// The file the line belongs to when it is not the program itself (a LinuxCNC
    /// subroutine file); `None` for the program.
    pub file: Option<std::sync::Arc<str>>,
    /// The subroutine calls that led to the error, innermost first: the file (`None` for
    /// the program) and line of each `call`.
    pub called_from: Vec<(Option<std::sync::Arc<str>>, u32)>,
}

impl Diagnostic {
    /// `PROGRAM:LINE:COL: error: MESSAGE`, where the error's file replaces `program` when
    /// it lies in a subroutine file, followed by one `FILE:LINE: note: called from here`
    /// line per call that led to it.
    pub fn render(&self, program: &str) -> String {
        use std::fmt::Write;
        let file = self.file.as_deref().unwrap_or(program);
        let mut s = format!("{file}:{}:{}: error: {}", self.line, self.col, self.message);
        for (f, line) in &self.called_from {
            let _ = write!(
                s,
                "\n{}:{line}: note: called from here",
                f.as_deref().unwrap_or(program)
            );
        }
        s
    }
}
