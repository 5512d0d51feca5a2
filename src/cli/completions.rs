//! `sagnac completions bash|zsh|fish`: the shell completion script (clap_complete).
//!
//! Install, e.g.: `sagnac completions bash > ~/.local/share/bash-completion/completions/sagnac`,
//! `sagnac completions zsh > ~/.zfunc/_sagnac`, `sagnac completions fish > ~/.config/fish/completions/sagnac.fish`.

use clap::{Args, CommandFactory, ValueEnum};
use clap_complete::Shell;

/// Shells with a completion script.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CompletionShell {
    Bash,
    Zsh,
    Fish,
}

/// Arguments of `sagnac completions`.
#[derive(Debug, Args)]
pub struct CompletionsArgs {
    /// The shell to complete for.
    #[arg(value_enum)]
    pub shell: CompletionShell,
}

/// Write the script to standard output.
pub fn run(args: CompletionsArgs) -> anyhow::Result<()> {
    let shell = match args.shell {
        CompletionShell::Bash => Shell::Bash,
        CompletionShell::Zsh => Shell::Zsh,
        CompletionShell::Fish => Shell::Fish,
    };
    let mut script = Vec::new();
    clap_complete::generate(shell, &mut super::Cli::command(), "sagnac", &mut script);
    super::write_stdout(String::from_utf8_lossy(&script).trim_end())
}
