//! Segment and junction limits and corner blending for Kerf.
#![deny(missing_docs)]
