//! Shell completions and man pages generated from a binary's clap definition.
//!
//! The `kerf` and `kerfd` binaries own their [`clap::Command`]s; each passes its own to
//! these functions (the hidden `kerf completions SHELL` and `kerf man DIR`, and `kerfd
//! --completions SHELL` and `kerfd --man DIR`), so the completions and man pages the
//! package installs are generated from the same definitions that parse the arguments and
//! cannot drift from them.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

pub use clap_complete::Shell;

/// The shells completions are generated for: bash, zsh and fish.
pub const SHELLS: [Shell; 3] = [Shell::Bash, Shell::Zsh, Shell::Fish];

/// Writes the completion script of `cmd` for `shell` to `out`, without its hidden
/// arguments and subcommands (clap_complete would offer them).
pub fn write_completions(cmd: clap::Command, shell: Shell, out: &mut dyn Write) {
    let mut cmd = visible(&cmd);
    let name = cmd.get_name().to_string();
    clap_complete::generate(shell, &mut cmd, name, out);
}

/// `cmd` with only what its help shows: the hidden arguments and subcommands left out.
fn visible(cmd: &clap::Command) -> clap::Command {
    let mut out = clap::Command::new(cmd.get_name().to_string());
    if let Some(about) = cmd.get_about() {
        out = out.about(about.clone());
    }
    if let Some(version) = cmd.get_version() {
        out = out.version(version.to_string());
    }
    out.args(
        cmd.get_arguments()
            .filter(|a| !a.is_hide_set())
            .cloned()
            .collect::<Vec<_>>(),
    )
    .subcommands(
        cmd.get_subcommands()
            .filter(|s| !s.is_hide_set())
            .map(visible)
            .collect::<Vec<_>>(),
    )
}

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
