//! Kerf's real-time motion core: segment queue, lookahead and jerk-limited interpolation.
#![deny(missing_docs)]
