//! The configuration's errors, each naming the file and, where TOML gives one, the place.

use std::io;

/// A 1-based place in a text file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextPosition {
    /// 1-based line.
    pub line: u32,
    /// 1-based column, in characters.
    pub col: u32,
}

/// Why a configuration could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{origin}: error: cannot read config: {source}")]
    Io {
        /// The file as named by the user.
        origin: String,
        /// The underlying error.
        source: io::Error,
    },
    /// The file is not valid TOML, has an unknown or missing key, or a value is out of range.
    #[error("{origin}:{}error: {message}", position_prefix(position))]
    Invalid {
        /// The file as named by the user.
        origin: String,
        /// Where in the file, when known.
        position: Option<TextPosition>,
        /// What is wrong, naming the key.
        message: String,
    },
}

fn position_prefix(position: &Option<TextPosition>) -> String {
    match position {
        Some(p) => format!("{}:{}: ", p.line, p.col),
        None => " ".to_string(),
    }
}
