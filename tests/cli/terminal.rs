//! What a terminal shows: `sagnac run` at a terminal (a real pseudo-terminal,
//! Python's `pty` module) redraws one status line in place (carriage returns,
//! line clears) with QN and ARW in fixed notation and the fit verdict; the same
//! run with stderr redirected writes log lines only, with no carriage return or
//! escape code; the long offline commands draw a progress bar at a terminal and
//! nothing when stderr is not one.

use std::path::Path;
use std::process::Command;

use crate::support::PAPER_GYRO;

const SAGNAC: &str = env!("CARGO_BIN_EXE_sagnac");

/// Run `args` with stderr on a pseudo-terminal 80 columns wide (stdout
/// discarded); what the terminal received, and the exit code.
fn on_pty(args: &[&str], cwd: &Path) -> (String, i32) {
    on_pty_cols(args, cwd, 80)
}

/// [`on_pty`] on a terminal `cols` columns wide.
fn on_pty_cols(args: &[&str], cwd: &Path, cols: u16) -> (String, i32) {
    const HELPER: &str = r#"
import fcntl, os, pty, select, struct, subprocess, sys, termios
master, slave = pty.openpty()
fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, int(os.environ["COLUMNS_PTY"]), 0, 0))
p = subprocess.Popen(sys.argv[1:], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave)
os.close(slave)
out = b""
while True:
    r, _, _ = select.select([master], [], [], 0.5)
    if r:
        try:
            d = os.read(master, 65536)
        except OSError:
            break
        if not d:
            break
        out += d
    elif p.poll() is not None:
        break
p.wait()
sys.stdout.buffer.write(out)
sys.exit(p.returncode)
"#;
    let out = Command::new("python3")
        .arg("-c")
        .arg(HELPER)
        .arg(SAGNAC)
        .args(args)
        .current_dir(cwd)
        .env_remove("RUST_LOG")
        .env("SAGNAC_PROGRESS_DELAY_S", "0")
        .env("COLUMNS_PTY", cols.to_string())
        .output()
        .expect("python3");
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        out.status.code().unwrap_or(-1),
    )
}

/// `Q <coefficient> arcsec` and `N <coefficient> deg/sqrt(h)` of a full status
/// line, or `Q <coefficient> N <coefficient> ok|MISFIT` of a compact one, each
/// coefficient "v [lo, hi]" or "< u" in fixed notation.
fn fixed_notation(line: &str) -> bool {
    let part = |from: &str, to: &[&str]| -> Option<String> {
        let a = line.find(from)? + from.len();
        let b = to.iter().filter_map(|t| line[a..].find(t)).min()? + a;
        Some(line[a..b].to_string())
    };
    let (q, n) = if line.contains(" arcsec") {
        (part("| Q ", &[" arcsec"]), part("| N ", &[" deg/sqrt(h)"]))
    } else {
        (part(" Q ", &[" N "]), part(" N ", &[" ok", " MISFIT"]))
    };
    [q, n].iter().all(|p| {
        p.as_ref().is_some_and(|t| {
            !t.is_empty()
                && t.chars()
                    .all(|c| c.is_ascii_digit() || " .,[]<".contains(c))
        })
    })
}

/// The status lines a terminal showed: each redraw, its escape codes removed.
fn status_lines(tty: &str, marker: &str) -> Vec<String> {
    tty.split(['\r', '\n'])
        .map(|l| {
            l.trim_start_matches("\x1b[2K")
                .trim_start_matches("\x1b[1A")
                .trim_start_matches("\x1b[1B")
                .trim()
                .to_string()
        })
        .filter(|l| l.contains(marker))
        .collect()
}

#[test]
fn run_at_a_terminal_redraws_one_status_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("c.toml"), "[estimator]\ninterval_s = 1.0\n").unwrap();
    let (tty, code) = on_pty(
        &[
            "run",
            "--config",
            "c.toml",
            "--duration-s",
            "3",
            "--metrics-addr",
            "",
            "--record-dir",
            "rec",
        ],
        dir.path(),
    );
    assert_eq!(code, 0, "{tty}");
    // redrawn in place: carriage return and erase-line before each redraw
    assert!(tty.contains("\r\x1b[2K"), "no in-place redraw: {tty:?}");
    // 80 columns: the compact line, which fits
    let lines = status_lines(&tty, " lost)");
    assert!(
        lines.len() >= 4,
        "the status line is redrawn while the run goes: {lines:?}"
    );
    for l in &lines {
        assert!(l.chars().count() <= 80, "wider than the terminal: {l:?}");
    }
    let last = lines.last().unwrap();
    assert!(last.contains(" 3000 (0 lost) "), "{last}");
    assert!(fixed_notation(last), "QN and ARW in fixed notation: {last}");
    assert!(
        last.ends_with(" ok") || last.ends_with(" MISFIT"),
        "the fit verdict: {last}"
    );
    // the elapsed time runs: the first status line says less than the last
    let secs = |l: &str| {
        l.split("s ")
            .next()
            .and_then(|t| t.trim().parse::<f64>().ok())
    };
    assert!(secs(&lines[0]).unwrap() < secs(last).unwrap(), "{lines:?}");
    // the intermediate estimate log lines are left to the status line; the final one stays
    assert_eq!(
        tty.matches("final_update\x1b[0m\x1b[2m=\x1b[0mfalse")
            .count(),
        0,
        "{tty}"
    );
    assert_eq!(
        tty.matches("final_update\x1b[0m\x1b[2m=\x1b[0mtrue")
            .count(),
        1,
        "{tty}"
    );
}

#[test]
fn run_without_a_terminal_writes_plain_log_lines() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("c.toml"), "[estimator]\ninterval_s = 1.0\n").unwrap();
    let out = Command::new(SAGNAC)
        .args([
            "run",
            "--config",
            "c.toml",
            "--duration-s",
            "3",
            "--metrics-addr",
            "",
            "--record-dir",
            "rec",
        ])
        .current_dir(dir.path())
        .env_remove("RUST_LOG")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        !err.contains('\r') && !err.contains('\x1b'),
        "progress or escape codes in {err:?}"
    );
    let estimates: Vec<&str> = err.lines().filter(|l| l.contains(" estimate ")).collect();
    // three interval updates and the final one; the simulated bench skips an
    // update that would take over 5 % of the wall time, as one may on a
    // loaded machine (the final one is always made)
    assert!(
        (2..=4).contains(&estimates.len()),
        "interval updates and the final one:\n{err}"
    );
    assert!(
        estimates.last().unwrap().contains("final_update=true"),
        "the last estimate is the final one:\n{err}"
    );
    for l in estimates {
        for key in ["quantization_arcsec=", "arw_dpsh=", "bias_instability_dph="] {
            let v = l
                .split(key)
                .nth(1)
                .unwrap_or_else(|| panic!("{key} in {l}"));
            // up to the next key=value field
            let v = v.split('=').next().unwrap();
            let v = v.rsplit_once(' ').map_or(v, |(a, _)| a);
            assert!(
                v.chars()
                    .all(|c| c.is_ascii_digit() || " .,[]<-".contains(c)),
                "{key}{v}: not fixed notation in {l}"
            );
        }
    }
}

/// The long offline commands: a bar on a terminal, nothing on a pipe.
#[test]
fn offline_commands_show_progress_on_a_terminal_only() {
    let dir = tempfile::tempdir().unwrap();
    let model = PAPER_GYRO;
    // long enough to pass the bar's 0.7 s delay on this machine (about 2 s)
    let sim = [
        "simulate",
        "--model",
        model,
        "--duration-s",
        "3000",
        "--seed",
        "1",
        "--format",
        "frames",
        "--out",
        "s.bin",
    ];
    let (tty, code) = on_pty(&sim, dir.path());
    assert_eq!(code, 0, "{tty}");
    assert!(
        tty.contains("simulating") && tty.contains("samples") && tty.contains('\r'),
        "{tty:?}"
    );
    for args in [
        sim.to_vec(),
        vec![
            "analyze",
            "--format",
            "frames",
            "--input",
            "s.bin",
            "--sample-rate-hz",
            "1000",
            "--pulse-arcsec",
            "1.21",
            "--json",
            "a.json",
        ],
    ] {
        plain_on_a_pipe(&args, dir.path());
    }
    // a wide terminal keeps the full status line
    let (tty, code) = on_pty_cols(
        &[
            "run",
            "--replay",
            "s.bin",
            "--sample-rate-hz",
            "1000",
            "--pulse-arcsec",
            "1.21",
            "--metrics-addr",
            "",
            "--record-dir",
            "",
        ],
        dir.path(),
        200,
    );
    assert_eq!(code, 0, "{tty}");
    assert!(
        tty.contains("replay 100 %"),
        "a replay shows its progress: {tty:?}"
    );
    let last = status_lines(&tty, " samples, ").pop().unwrap_or_default();
    assert!(last.contains("| Q ") && fixed_notation(&last), "{last:?}");
    // the diagnosis: a bar of its Monte-Carlo runs, phase by phase
    let short = [
        "simulate",
        "--model",
        model,
        "--duration-s",
        "60",
        "--seed",
        "2",
        "--format",
        "frames",
        "--out",
        "d.bin",
    ];
    let (tty, code) = on_pty(&short, dir.path());
    assert_eq!(code, 0, "{tty}");
    let diag = [
        "diagnose",
        "--model",
        model,
        "--input",
        "d.bin",
        "--format",
        "frames",
        "--runs",
        "4",
        "--runs-after",
        "2",
        "--json",
        "d.json",
    ];
    let (tty, code) = on_pty(&diag, dir.path());
    assert_eq!(code, 0, "{tty}");
    assert!(
        tty.contains("simulating the model") && tty.contains("/4 runs"),
        "the diagnosis's bar: {tty:?}"
    );
    plain_on_a_pipe(&diag, dir.path());
}

/// `args` run with stderr on a pipe succeed and write no progress (no carriage
/// return, no escape code).
fn plain_on_a_pipe(args: &[&str], cwd: &Path) {
    let out = Command::new(SAGNAC)
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{args:?}: {err}");
    assert!(
        !err.contains('\r') && !err.contains('\x1b'),
        "{args:?}: progress on a pipe: {err:?}"
    );
}
