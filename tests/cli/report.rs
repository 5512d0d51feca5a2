//! `sagnac report`: the self-contained HTML page and the PNG figures, the
//! data-quality findings and the dynamic Allan deviation on a record that
//! warms up and takes a bias step, and the page in headless Chromium: it loads with no console
//! message and no network request, and a screenshot is taken
//! (`target/report-screenshots/`). Without Chromium the browser test skips
//! with a notice, unless CI=true (scripts/install-peers installs it).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::support::{PAPER_GYRO, sagnac};

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The paper's gyro with a thermal model, as a frame capture (which carries
/// temperatures and gives decoder counts).
fn simulate(dir: &Path, seconds: &str) -> (PathBuf, PathBuf) {
    let model = dir.join("thermal.toml");
    let text = std::fs::read_to_string(PAPER_GYRO).unwrap()
        + "\n[thermal]\ntemp_c0 = 25.0\nramp_c_per_h = 6.0\nsine_amplitude_c = 0.5\nsine_period_s = 100.0\n\
           bias_sensitivity_dph_per_c = 0.01\n";
    std::fs::write(&model, text).unwrap();
    let bin = dir.join("run.bin");
    let o = sagnac(&[
        "simulate",
        "--model",
        model.to_str().unwrap(),
        "--duration-s",
        seconds,
        "--seed",
        "7",
        "--format",
        "frames",
        "--out",
        bin.to_str().unwrap(),
    ]);
    ok(&o);
    (bin, model)
}

/// Width and height of a PNG file (its IHDR).
fn png_size(p: &Path) -> (u32, u32) {
    let b = std::fs::read(p).unwrap();
    assert_eq!(
        &b[..8],
        b"\x89PNG\r\n\x1a\n",
        "{} is not a PNG",
        p.display()
    );
    assert_eq!(&b[12..16], b"IHDR");
    let be = |i: usize| u32::from_be_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    (be(16), be(20))
}

/// The chunk types of a PNG file, each chunk's CRC checked, and the file
/// ending with its IEND chunk.
fn png_chunks(p: &Path) -> Vec<String> {
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 == 1 {
                    (c >> 1) ^ 0xEDB8_8320
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    let b = std::fs::read(p).unwrap();
    assert_eq!(
        &b[..8],
        b"\x89PNG\r\n\x1a\n",
        "{} is not a PNG",
        p.display()
    );
    let mut at = 8;
    let mut kinds = Vec::new();
    while at < b.len() {
        let len = u32::from_be_bytes(b[at..at + 4].try_into().unwrap()) as usize;
        let body = &b[at + 4..at + 8 + len];
        let crc = u32::from_be_bytes(b[at + 8 + len..at + 12 + len].try_into().unwrap());
        let kind = String::from_utf8_lossy(&body[..4]).into_owned();
        assert_eq!(crc32(body), crc, "{}: bad CRC in chunk {kind}", p.display());
        kinds.push(kind);
        at += 12 + len;
    }
    assert_eq!(at, b.len(), "{}: truncated chunk", p.display());
    assert_eq!(kinds.last().map(String::as_str), Some("IEND"));
    kinds
}

#[test]
fn report_writes_a_self_contained_page_and_its_pngs() {
    let dir = tempfile::tempdir().unwrap();
    let (bin, model) = simulate(dir.path(), "120");
    let out = dir.path().join("rep");
    let o = sagnac(&[
        "report",
        "--format",
        "frames",
        "--input",
        bin.to_str().unwrap(),
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
        "--out",
        out.to_str().unwrap(),
        "--model",
        model.to_str().unwrap(),
    ]);
    ok(&o);
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert_eq!(
        png_size(&out.join("allan.png")),
        sagnac::sink::report::ALLAN_SIZE
    );
    assert_eq!(
        png_size(&out.join("noise_integral.png")),
        sagnac::sink::report::NOISE_SIZE
    );
    assert_eq!(
        png_size(&out.join("davar.png")),
        sagnac::sink::report::DAVAR_SIZE
    );
    // self-contained: no script, no stylesheet or font link, no outside source
    let lower = html.to_lowercase();
    for bad in [
        "<script", "<link", "<img", "@import", "url(", "src=", "href=",
    ] {
        assert!(!lower.contains(bad), "the page holds {bad}");
    }
    // the only URL is the SVG namespace (a name, not a request)
    let urls: Vec<&str> = html
        .match_indices("http:")
        .chain(html.match_indices("https:"))
        .map(|(i, _)| &html[i..(i + 26).min(html.len())])
        .collect();
    assert!(
        urls.iter()
            .all(|u| u.starts_with("http://www.w3.org/2000/svg")),
        "{urls:?}"
    );
    assert!(
        html.contains("default-src 'none'"),
        "no Content-Security-Policy"
    );
    // the page's sections
    for id in [
        "recording",
        "coefficients",
        "quality",
        "allan",
        "noise",
        "rate",
        "davar",
        "diagnosis",
    ] {
        assert!(
            html.contains(&format!("<section id=\"{id}\">")),
            "no section {id}"
        );
    }
    assert_eq!(
        html.matches("<svg").count(),
        5,
        "Allan, noise, rate, dynamic Allan deviation and diagnosis figures"
    );
    for text in [
        "quantization noise",
        "angle random walk",
        "fit.ok = ",
        "Readout filter",
        "120000",
        "1000 Hz",
        "1.21 arcsec",
        "CRC errors",
        "gaps",
        "temperature",
        "Verdict:",
        "Notes of the diagnosis",
        "\u{221a}3\u{b7}Q/\u{3c4}",
        "N/\u{221a}\u{3c4}",
        "\u{b1}1 pulse",
    ] {
        assert!(html.contains(text), "the page lacks {text:?}");
    }
}

/// A rate gyro whose bias settles after switch-on (8 deg/h, tau 300 s) and
/// steps by 3 deg/h at 1200 s, 40 min at 200 Hz, as CSV. The warm-up is
/// four times the size at which the data-quality stage starts finding it
/// beside this bias instability, so the seed's record has both findings.
fn simulate_transients(dir: &Path) -> PathBuf {
    let model = dir.join("transients.toml");
    std::fs::write(
        &model,
        "[gyro]\nsample_rate_hz = 200.0\noutput = \"rate\"\nrate_lsb_dps = 0.0005\ninput_rate_dph = 10.0\n\n\
         [noise]\narw_dpsh = 0.05\nbias_instability_dph = 0.3\n\n\
         [noise.warmup]\namplitude_dph = 8.0\ntau_s = 300.0\n\n\
         [[noise.bias_step]]\nat_s = 1200.0\namplitude_dph = 3.0\n",
    )
    .unwrap();
    let csv = dir.join("x.csv");
    ok(&sagnac(&[
        "simulate",
        "--model",
        model.to_str().unwrap(),
        "--duration-s",
        "2400",
        "--seed",
        "4",
        "--out",
        csv.to_str().unwrap(),
    ]));
    csv
}

/// `sagnac report` of `csv` (a rate column in deg/s at 200 Hz) into `out`, with `extra` flags.
fn report_rate_csv(csv: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "report",
        "--input",
        csv.to_str().unwrap(),
        "--column",
        "rate_dps",
        "--unit",
        "dps",
        "--sample-rate-hz",
        "200",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let o = sagnac(&args);
    ok(&o);
    o
}

/// The text of the page's section `id`.
fn section<'h>(html: &'h str, id: &str) -> &'h str {
    let start = html
        .find(&format!("<section id=\"{id}\">"))
        .unwrap_or_else(|| panic!("no section {id}"));
    let end = start + html[start..].find("</section>").unwrap();
    &html[start..end]
}

/// The x coordinates of the vertical polylines stroked in `color` in `svg`.
fn vertical_lines(svg: &str, color: &str) -> Vec<f64> {
    let head = format!("stroke=\"{color}\" stroke-width=\"2\" points=\"");
    svg.match_indices(&head)
        .filter_map(|(i, _)| {
            let pts = &svg[i + head.len()..];
            let pts = &pts[..pts.find('"').unwrap()];
            let xy: Vec<(f64, f64)> = pts
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect();
            (xy.len() == 2 && xy[0].0 == xy[1].0 && xy[0].1 != xy[1].1).then_some(xy[0].0)
        })
        .collect()
}

/// The x coordinate of the x-axis tick label `label` (a `<text>` centred
/// on its tick) in `svg`.
fn tick_x(svg: &str, label: &str) -> f64 {
    let body = format!(">\n{label}\n</text>");
    svg.match_indices(&body)
        .find_map(|(end, _)| {
            let start = svg[..end].rfind("<text ")?;
            let tag = &svg[start..end];
            if !tag.contains("text-anchor=\"middle\"") {
                return None;
            }
            let x = &tag[tag.find("x=\"")? + 3..];
            x[..x.find('"')?].parse().ok()
        })
        .unwrap_or_else(|| panic!("no x tick {label}"))
}

fn hex(c: plotters::style::RGBColor) -> String {
    format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
}

#[test]
fn report_shows_the_data_quality_findings_and_the_dynamic_allan_deviation() {
    let dir = tempfile::tempdir().unwrap();
    let csv = simulate_transients(dir.path());
    let out = dir.path().join("rep");
    let o = report_rate_csv(&csv, &out, &[]);
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("davar.png"),
        "the files written are not listed"
    );
    let davar = out.join("davar.png");
    assert_eq!(png_size(&davar), sagnac::sink::report::DAVAR_SIZE);
    let chunks = png_chunks(&davar);
    assert_eq!(chunks[0], "IHDR");
    assert!(chunks.iter().any(|c| c == "IDAT"));
    // a drawn map, not a blank canvas (a white 1150x520 PNG is about 3 kB)
    assert!(std::fs::metadata(&davar).unwrap().len() > 20_000);

    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    // the data-quality section follows the coefficient table
    let at = |id: &str| html.find(&format!("<section id=\"{id}\">")).unwrap();
    assert!(at("coefficients") < at("quality") && at("quality") < at("allan"));
    let quality = section(&html, "quality");
    assert!(quality.contains("<h2>Data quality</h2>"));
    assert!(quality.contains("<li>warm-up: +"), "{quality}");
    // the step's line, and its time within 30 s of the simulated 1200 s
    let step = &quality[quality.find("<li>bias step: +").expect(quality)..];
    let t: f64 = step[step.find(" at ").unwrap() + 4..]
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((t - 1200.0).abs() < 30.0, "step at {t} s");
    assert!(
        quality.contains("Stationarity of what remains"),
        "{quality}"
    );

    let map = section(&html, "davar");
    assert!(map.contains("<h2>Dynamic Allan deviation</h2>"));
    assert!(map.contains("<figure><svg"), "no heat map: {map}");
    assert!(map.contains("ADEV, deg/h"), "no colour bar label");
    assert!(map.contains("change along time"));
    assert_eq!(
        html.matches("<svg").count(),
        4,
        "Allan, noise, rate and map"
    );

    // the rate figure: the step's line at the 20 min tick (1 min is 26 px),
    // its interval shaded, the warm-up curve and the legend entries
    let rate = section(&html, "rate");
    let lines = vertical_lines(rate, &hex(sagnac::sink::report::plot::STEP));
    let tick = tick_x(rate, "20");
    assert!(
        lines.iter().any(|x| (x - tick).abs() < 26.0),
        "no step line near x = {tick}: {lines:?}"
    );
    let shade = format!(
        "opacity=\"0.15\" fill=\"{}\"",
        hex(sagnac::sink::report::plot::STEP)
    );
    assert!(
        rate.matches(&shade).count() >= 2,
        "no shaded interval (plot and legend)"
    );
    assert!(rate.contains(&format!(
        "stroke=\"{}\" stroke-width=\"2\"",
        hex(sagnac::sink::report::plot::WARMUP)
    )));
    for text in ["bias step, 95 % interval shaded", "fitted warm-up"] {
        assert!(rate.contains(text), "the rate legend lacks {text:?}");
    }
}

#[test]
fn report_with_raw_statistics_says_the_stage_is_off_and_draws_no_map() {
    let dir = tempfile::tempdir().unwrap();
    let csv = simulate_transients(dir.path());
    let out = dir.path().join("rep");
    // a first report leaves a map, which the raw-statistics one removes
    report_rate_csv(&csv, &out, &[]);
    assert!(out.join("davar.png").exists());
    let o = report_rate_csv(&csv, &out, &["--raw-statistics"]);
    assert!(!String::from_utf8_lossy(&o.stdout).contains("davar.png"));
    assert!(!out.join("davar.png").exists(), "a stale davar.png is left");
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(
        section(&html, "quality").contains("data-quality stage off (--raw-statistics)"),
        "{}",
        section(&html, "quality")
    );
    let map = section(&html, "davar");
    assert!(!map.contains("<svg"), "a map without the stage: {map}");
    assert!(map.contains("the data-quality stage is off"), "{map}");
    assert_eq!(html.matches("<svg").count(), 3, "Allan, noise and rate");
    // nothing handled, nothing marked on the rate
    let rate = section(&html, "rate");
    for c in [
        sagnac::sink::report::plot::STEP,
        sagnac::sink::report::plot::WARMUP,
        sagnac::sink::report::plot::OUTLIER,
    ] {
        assert!(!rate.contains(&hex(c)), "{} marked", hex(c));
    }
}

#[test]
fn report_rejects_bad_input_flags() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("x.csv");
    std::fs::write(&csv, "counts\n1\n2\n").unwrap();
    let out = dir.path().join("o");
    let out_s = out.to_str().unwrap();
    let cases: [(&[&str], &str); 4] = [
        (
            &["report", "--input", csv.to_str().unwrap(), "--out", out_s],
            "--sample-rate-hz is required",
        ),
        (
            &[
                "report",
                "--input",
                csv.to_str().unwrap(),
                "--sample-rate-hz",
                "1000",
                "--out",
                out_s,
            ],
            "--pulse-arcsec is required",
        ),
        (
            &[
                "report",
                "--input",
                csv.to_str().unwrap(),
                "--sample-rate-hz",
                "-3",
                "--out",
                out_s,
            ],
            "--sample-rate-hz must be",
        ),
        (
            &[
                "report",
                "--input",
                csv.to_str().unwrap(),
                "--sample-rate-hz",
                "1000",
                "--unit",
                "dph",
                "--out",
                out_s,
                "--model",
                PAPER_GYRO,
            ],
            "the model is a pulse counter",
        ),
    ];
    for (args, want) in cases {
        let o = sagnac(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
    }
    // --out naming a file
    let o = sagnac(&[
        "report",
        "--input",
        csv.to_str().unwrap(),
        "--sample-rate-hz",
        "1",
        "--pulse-arcsec",
        "1",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a directory"));
}

fn chromium() -> Option<PathBuf> {
    for name in ["chromium", "chromium-browser", "google-chrome"] {
        let found = Command::new("sh")
            .arg("-c")
            .arg(format!("command -v {name}"))
            .output()
            .ok()?;
        if found.status.success() {
            return Some(PathBuf::from(String::from_utf8_lossy(&found.stdout).trim()));
        }
    }
    None
}

/// Load `page` in headless Chromium; returns (console messages, requests
/// the page made). The browser's own background services (update, time,
/// accounts) are not the page's and are left out.
fn load(chrome: &Path, page: &Path, shot: &Path, profile: &Path) -> (Vec<String>, Vec<String>) {
    let o = Command::new(chrome)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-default-apps",
            "--disable-extensions",
            "--window-size=1400,4200",
            "--enable-logging=stderr",
            "--v=1",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let log = String::from_utf8_lossy(&o.stderr).into_owned();
    let page_url = format!("file://{}", page.display());
    // only what comes after the page starts loading
    let start = log
        .find(&format!("FileURLLoader::Start: {page_url}"))
        .expect("chromium never loaded the page");
    let after = &log[start..];
    let browser_own = [
        "google.com/",
        "googleapis.com/",
        "gvt1.com/",
        "gstatic.com/",
    ];
    let console = after
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(String::from)
        .collect();
    let requests = after
        .lines()
        .filter_map(|l| {
            l.split_once("NotifyBeforeURLRequest: ")
                .map(|(_, u)| u)
                .or_else(|| l.split_once("FileURLLoader::Start: ").map(|(_, u)| u))
        })
        .filter(|u| *u != page_url && !browser_own.iter().any(|h| u.contains(h)))
        .map(String::from)
        .collect();
    (console, requests)
}

#[test]
fn the_page_loads_in_chromium_without_errors_or_requests() {
    let Some(chrome) = chromium() else {
        if std::env::var("CI").as_deref() == Ok("true") {
            panic!("chromium is missing on CI: scripts/install-peers installs it");
        }
        eprintln!(
            "NOTICE: chromium not found: skipping the browser test (apt-get install chromium)"
        );
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (bin, model) = simulate(dir.path(), "120");
    let out = dir.path().join("rep");
    ok(&sagnac(&[
        "report",
        "--format",
        "frames",
        "--input",
        bin.to_str().unwrap(),
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
        "--out",
        out.to_str().unwrap(),
        "--model",
        model.to_str().unwrap(),
    ]));
    let shots = Path::new(env!("CARGO_TARGET_TMPDIR")).join("report-screenshots");
    std::fs::create_dir_all(&shots).unwrap();
    let profile = dir.path().join("profile");

    // the detector itself: a page with a script error and an outside image is caught
    let bad = dir.path().join("bad.html");
    std::fs::write(&bad, "<html><body><img src=\"http://example.invalid/x.png\"><script>console.error('boom')</script></body></html>")
        .unwrap();
    let (console, requests) = load(&chrome, &bad, &shots.join("bad.png"), &profile);
    assert!(
        console.iter().any(|l| l.contains("boom")),
        "console not seen: {console:?}"
    );
    assert!(
        requests.iter().any(|u| u.contains("example.invalid")),
        "request not seen: {requests:?}"
    );

    let page = out.join("index.html").canonicalize().unwrap();
    let shot = shots.join("index.png");
    let (console, requests) = load(&chrome, &page, &shot, &profile);
    assert!(console.is_empty(), "console messages: {console:#?}");
    assert!(requests.is_empty(), "the page made requests: {requests:#?}");
    let (w, h) = png_size(&shot);
    assert_eq!((w, h), (1400, 4200));
    assert!(
        std::fs::metadata(&shot).unwrap().len() > 50_000,
        "a near-blank screenshot"
    );
    eprintln!("screenshot: {}", shot.display());
}

#[test]
fn report_with_a_spec_shows_the_same_verdict_as_analyze() {
    let dir = tempfile::tempdir().unwrap();
    let (bin, _model) = simulate(dir.path(), "120");
    let spec = concat!(env!("CARGO_MANIFEST_DIR"), "/config/spec_example.toml");
    let out = dir.path().join("rep");
    let flags = [
        "--format",
        "frames",
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
        "--spec",
        spec,
    ];
    let mut args = vec![
        "report",
        "--input",
        bin.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(flags);
    ok(&sagnac(&args));
    let mut args = vec!["analyze", "--input", bin.to_str().unwrap(), "--json", "-"];
    args.extend(flags);
    let o = sagnac(&args);
    ok(&o);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    let overall = v["spec"]["verdict"].as_str().unwrap();
    assert!(
        html.contains(&format!("<h2>Acceptance test: {overall}</h2>")),
        "overall verdict {overall} not shown"
    );
    for (name, c) in v["spec"]["coefficients"].as_object().unwrap() {
        let verdict = c["verdict"].as_str().unwrap();
        let row = format!("<tr><td><code>{name}</code></td>");
        let at = html
            .find(&row)
            .unwrap_or_else(|| panic!("no row for {name}"));
        let end = at + html[at..].find("</tr>").unwrap();
        assert!(
            html[at..end].contains(&format!("<td>{verdict}</td>")),
            "{name}: {}",
            &html[at..end]
        );
    }
}
