//! The Dockerfile, checked without Docker (no daemon here): its default command
//! is a valid `sagnac run` command line, run for real with the image's paths
//! mapped to a temporary directory and its `0.0.0.0:9898` to a free loopback
//! port; the health check requests the path that command serves; the exposed
//! port, the command's port and the health check's port agree; `.dockerignore`
//! keeps target/ out of the build context.

use std::time::Duration;

use crate::support::daemon::{DaemonProc, metric, scrape, wait_for};
use crate::support::{free_addr, repo};

/// The JSON array of a Dockerfile instruction (`CMD [...]`), joined over `\` continuations.
fn exec_form(dockerfile: &str, instruction: &str) -> Vec<String> {
    let joined = dockerfile.replace("\\\n", " ");
    let line = joined
        .lines()
        .rev()
        .find_map(|l| l.trim().strip_prefix(&format!("{instruction} ")))
        .unwrap_or_else(|| panic!("no {instruction} in the Dockerfile"));
    let json = &line[line
        .find('[')
        .unwrap_or_else(|| panic!("{instruction} is not in exec form: {line}"))..];
    serde_json::from_str(json).unwrap_or_else(|e| panic!("{instruction} {json}: {e}"))
}

#[test]
fn the_image_command_serves_metrics_on_the_exposed_port_and_the_health_check_reads_them() {
    let text = std::fs::read_to_string(repo().join("Dockerfile")).unwrap();
    assert!(
        text.contains("cargo build --release --locked"),
        "the builder stage builds with --locked"
    );
    let entry = exec_form(&text, "ENTRYPOINT");
    // the last line starting with CMD (the health check's CMD is inside its HEALTHCHECK line)
    let cmd = exec_form(&text, "CMD");
    assert_eq!(entry, vec!["/usr/local/bin/sagnac"]);
    let at = cmd
        .iter()
        .position(|a| a == "--metrics-addr")
        .expect("the default command sets --metrics-addr");
    assert_eq!(
        cmd[at + 1],
        "0.0.0.0:9898",
        "inside the container /metrics must be reachable through -p 9898:9898"
    );
    assert!(
        text.lines().any(|l| l.trim() == "EXPOSE 9898"),
        "EXPOSE 9898"
    );
    let hc_line = text.replace("\\\n", " ");
    let hc = hc_line
        .lines()
        .find(|l| l.starts_with("HEALTHCHECK"))
        .expect("a HEALTHCHECK");
    let url = hc
        .split('"')
        .find(|s| s.starts_with("http://"))
        .expect("the health check's URL");
    assert_eq!(url, "http://127.0.0.1:9898/metrics", "{hc}");
    assert!(
        hc.contains("\"curl\"") && text.contains("apt-get install -y --no-install-recommends curl"),
        "curl is installed for it"
    );
    let ignore = std::fs::read_to_string(repo().join(".dockerignore")).unwrap();
    assert!(ignore.lines().any(|l| l.trim() == "target/"), "{ignore}");

    // Run the default command with the image's paths mapped here.
    let dir = tempfile::tempdir().unwrap();
    let addr = free_addr();
    let args: Vec<String> = cmd
        .iter()
        .map(|a| match a.as_str() {
            "0.0.0.0:9898" => addr.to_string(),
            _ => a
                .replace("/etc/sagnac", repo().join("config").to_str().unwrap())
                .replace("/var/lib/sagnac", dir.path().to_str().unwrap()),
        })
        .collect();
    assert!(
        args.iter()
            .all(|a| !a.starts_with("/etc/") && !a.starts_with("/var/")),
        "unmapped path in {args:?}"
    );
    std::fs::create_dir_all(dir.path().join("recordings")).unwrap();
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    let mut d = DaemonProc::start(&argv, &dir.path().join("log"));
    let body = wait_for(
        "/metrics of the image's command",
        Duration::from_secs(30),
        || {
            let t = scrape(addr)?;
            metric(&t, "sagnac_samples_total{gyro=\"gyro\"}")
                .filter(|n| *n > 0.0)
                .map(|_| t)
        },
    );
    assert!(body.contains("sagnac_build_info"), "{body}");
    d.sigterm();
    let status = d.wait(Duration::from_secs(20));
    assert!(status.success(), "{status:?}\n{}", d.log_text());
    // the default command records into the mounted directory
    assert_eq!(
        std::fs::read_dir(dir.path().join("recordings"))
            .unwrap()
            .count(),
        1,
        "{}",
        d.log_text()
    );
}
