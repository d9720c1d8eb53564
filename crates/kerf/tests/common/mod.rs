//! What the tests that start `kerf` and `kerfd` as processes share.

use std::path::Path;
use std::sync::OnceLock;

/// The `kerfd` binary beside `kerf` in the target directory. It belongs to the `kerfd`
/// package, whose binary cargo builds for the workspace's tests (`cargo test --workspace`)
/// but not for `cargo test -p kerf` alone: then this fails and says so.
pub fn kerfd() -> &'static str {
    static PATH: OnceLock<String> = OnceLock::new();
    PATH.get_or_init(|| {
        let path = Path::new(env!("CARGO_BIN_EXE_kerf")).with_file_name("kerfd");
        assert!(
            path.is_file(),
            "{} is missing: these tests start the daemon of the `kerfd` package; run \
             `cargo test --workspace`, or `cargo build -p kerfd` before `cargo test -p kerf`",
            path.display()
        );
        path.display().to_string()
    })
}
