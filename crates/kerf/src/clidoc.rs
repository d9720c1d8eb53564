//! Shell completions and man pages generated from a binary's clap definition.
//!
//! The `kerf` and `kerfd` binaries own their [`clap::Command`]s (`kerfd`'s is
//! [`kerfd::cli::Args`]); the hidden `kerf completions SHELL`, `kerf man DIR` and `kerfd
//! --completions SHELL` pass them to these functions, so the completions and man pages the
//! package installs are generated from the same definitions that parse the arguments and
//! cannot drift from them. `kerf man DIR` writes `kerfd`'s page too: the daemon does not
//! carry the man-page generator.

use std::io;
use std::path::{Path, PathBuf};

pub use kerfd::cli::{SHELLS, Shell, write_completions};

/// Writes the man page of `cmd` (section 1) and one for each of its visible subcommands
/// (`kerf-plan.1`, ...) into `dir`, creating it; returns the files written, the command's
/// own page first.
pub fn write_man_pages(cmd: clap::Command, dir: &Path) -> io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let mut cmd = cmd;
    cmd.build();
    let mut written = Vec::new();
    let name = cmd.get_name().to_string();
    written.push(write_page(cmd.clone(), &name, dir)?);
    for sub in cmd.get_subcommands() {
        if sub.is_hide_set() || sub.get_name() == "help" {
            continue;
        }
        let page = format!("{name}-{}", sub.get_name());
        // The page's title and synopsis name the whole command (`kerf plan`), and its
        // version is the parent's.
        let sub = sub
            .clone()
            .name(page.clone())
            .bin_name(format!("{name} {}", sub.get_name()))
            .version(cmd.get_version().unwrap_or_default().to_string());
        written.push(write_page(sub, &page, dir)?);
    }
    Ok(written)
}

fn write_page(cmd: clap::Command, page: &str, dir: &Path) -> io::Result<PathBuf> {
    let path = dir.join(format!("{page}.1"));
    let mut text = Vec::new();
    clap_mangen::Man::new(cmd)
        .title(page.to_uppercase())
        .section("1")
        .source(format!("Kerf {}", env!("CARGO_PKG_VERSION")))
        .manual("Kerf")
        .render(&mut text)?;
    std::fs::write(&path, text)?;
    Ok(path)
}
