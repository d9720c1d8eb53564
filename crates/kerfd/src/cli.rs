//! The command line of `kerfd` (its clap definition, here so that `kerf man` can write
//! the daemon's man page from it) and shell completions generated from a clap definition.

use std::io::Write;
use std::path::PathBuf;

use clap::Parser;
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

/// The arguments of `kerfd`.
#[derive(Debug, Parser)]
#[command(name = "kerfd", version, about = "Kerf real-time interpolator daemon")]
pub struct Args {
    /// Machine configuration (TOML). Without it: /etc/kerf/kerf.toml if present, else the
    /// built-in example machine.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Tests only: accept the fault injections of the control service (REQUEST_INJECT).
    #[arg(long, hide = true)]
    pub test_faults: bool,
    /// Packaging: print the shell completion script (bash, zsh or fish) and exit.
    #[arg(long, hide = true, value_name = "SHELL")]
    pub completions: Option<Shell>,
}
