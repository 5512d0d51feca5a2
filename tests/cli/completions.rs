//! `sagnac completions`: the scripts load in their shells and know the subcommands.

use std::process::Command;

fn script(shell: &str) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["completions", shell])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

#[test]
fn bash_completion_registers_and_completes_subcommands() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("sagnac.bash");
    std::fs::write(&f, script("bash")).unwrap();
    // source it in a real bash, check the registration, and complete `sagnac an`
    let probe = format!(
        "source {}; complete -p sagnac; COMP_WORDS=(sagnac an); COMP_CWORD=1; _sagnac sagnac an sagnac; echo \"${{COMPREPLY[@]}}\"",
        f.display()
    );
    let o = Command::new("bash")
        .args(["--norc", "-c", &probe])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "bash: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(out.contains("-F _sagnac sagnac"), "{out}");
    assert!(
        out.lines()
            .last()
            .unwrap_or("")
            .split_whitespace()
            .any(|w| w == "analyze"),
        "{out}"
    );
}

#[test]
fn zsh_and_fish_scripts_name_every_subcommand() {
    let zsh = script("zsh");
    assert!(
        zsh.starts_with("#compdef sagnac"),
        "{}",
        &zsh[..60.min(zsh.len())]
    );
    let fish = script("fish");
    for sub in [
        "run",
        "analyze",
        "allan",
        "simulate",
        "diagnose",
        "report",
        "completions",
    ] {
        assert!(zsh.contains(&format!("'{sub}:")), "zsh lacks {sub}");
        assert!(fish.contains(&format!("-a \"{sub}\"")), "fish lacks {sub}");
    }
    let o = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["completions", "tcsh"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
}
