//! G-code front end for Kerf: lexing, dialects, modal state and exact move resolution.
#![deny(missing_docs)]
