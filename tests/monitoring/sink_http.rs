//! The `/metrics` HTTP endpoint, scraped with plain HTTP/1.1 over a tokio
//! TcpStream on 127.0.0.1: status, content type, live values, 404s, and
//! graceful shutdown.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use sagnac::daemon::http::{DEFAULT_METRICS_ADDR, bind};
use sagnac::sink::metrics::{Bounds95, FrameErrorKind, GyroInfo, Metrics};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::sync::watch;

/// One request on a fresh connection; returns (status code, headers, body).
async fn request(addr: SocketAddr, method: &str, path: &str) -> (u16, String, String) {
    let mut s = TcpStream::connect(addr).await.unwrap();
    let req = format!("{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
    s.write_all(req.as_bytes()).await.unwrap();
    let mut raw = Vec::new();
    tokio::time::timeout(Duration::from_secs(10), s.read_to_end(&mut raw))
        .await
        .expect("response within 10 s")
        .unwrap();
    let text = String::from_utf8(raw).unwrap();
    let (head, body) = text.split_once("\r\n\r\n").expect("header/body split");
    let status: u16 = head.split(' ').nth(1).unwrap().parse().unwrap();
    (status, head.to_ascii_lowercase(), body.to_string())
}

fn value(body: &str, series: &str) -> Option<f64> {
    body.lines()
        .find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
}

#[test]
fn default_address_is_loopback_9898() {
    assert_eq!(DEFAULT_METRICS_ADDR.to_string(), "127.0.0.1:9898");
}

#[tokio::test]
async fn serves_metrics_and_404() {
    let metrics = Arc::new(Metrics::new().unwrap());
    let (stop_tx, stop_rx) = watch::channel(false);
    let (addr, server) = bind(
        "127.0.0.1:0".parse().unwrap(),
        Arc::clone(&metrics),
        stop_rx,
    )
    .await
    .unwrap();
    assert_ne!(addr.port(), 0);
    let server = tokio::spawn(server);

    let gyro = metrics.gyro(&GyroInfo::labelled("gyro"));
    gyro.add_samples(500);
    gyro.add_frame_errors(FrameErrorKind::Crc, 2);
    gyro.set_qn_arcsec(Bounds95 {
        estimate: Some(0.25),
        lower95: Some(0.2),
        upper95: Some(0.3),
    });
    let (status, head, body) = request(addr, "GET", "/metrics").await;
    assert_eq!(status, 200);
    assert!(
        head.contains("content-type: text/plain; version=0.0.4"),
        "{head}"
    );
    assert_eq!(
        value(&body, "sagnac_samples_total{gyro=\"gyro\"}"),
        Some(500.0)
    );
    assert_eq!(
        value(
            &body,
            "sagnac_frame_errors_total{gyro=\"gyro\",kind=\"crc\"}"
        ),
        Some(2.0)
    );
    assert_eq!(
        value(
            &body,
            "sagnac_qn_arcseconds{bound=\"lower95\",gyro=\"gyro\"}"
        ),
        Some(0.2)
    );

    // Live: the next scrape sees the update.
    gyro.add_samples(24);
    metrics.set_recording_bytes(4096);
    let (_, _, body) = request(addr, "GET", "/metrics?x=1").await;
    assert_eq!(
        value(&body, "sagnac_samples_total{gyro=\"gyro\"}"),
        Some(524.0)
    );
    assert_eq!(value(&body, "sagnac_recording_bytes"), Some(4096.0));

    for (method, path) in [
        ("GET", "/"),
        ("GET", "/metricsx"),
        ("GET", "/metrics/"),
        ("POST", "/metrics"),
    ] {
        let (status, _, body) = request(addr, method, path).await;
        assert_eq!(status, 404, "{method} {path}");
        assert!(!body.contains("sagnac_"), "{method} {path}");
    }

    // Graceful shutdown: an idle keep-alive connection does not hold it up.
    let mut idle = TcpStream::connect(addr).await.unwrap();
    idle.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .unwrap();
    let mut buf = [0u8; 64];
    let n = idle.read(&mut buf).await.unwrap();
    assert!(buf[..n].starts_with(b"HTTP/1.1 200"));
    stop_tx.send(true).unwrap();
    tokio::time::timeout(Duration::from_secs(10), server)
        .await
        .expect("server stops within 10 s")
        .unwrap();
    assert!(TcpStream::connect(addr).await.is_err(), "listener closed");
}

#[tokio::test]
async fn dropped_signal_sender_stops_the_server() {
    let metrics = Arc::new(Metrics::new().unwrap());
    let (stop_tx, stop_rx) = watch::channel(false);
    let (addr, server) = bind("127.0.0.1:0".parse().unwrap(), metrics, stop_rx)
        .await
        .unwrap();
    let server = tokio::spawn(server);
    assert_eq!(request(addr, "GET", "/metrics").await.0, 200);
    drop(stop_tx);
    tokio::time::timeout(Duration::from_secs(10), server)
        .await
        .expect("server stops")
        .unwrap();
}

#[tokio::test]
async fn bind_error_names_the_address() {
    let metrics = Arc::new(Metrics::new().unwrap());
    let (_tx, rx) = watch::channel(false);
    let (addr, _server) = bind(
        "127.0.0.1:0".parse().unwrap(),
        Arc::clone(&metrics),
        rx.clone(),
    )
    .await
    .unwrap();
    // The port is taken by the first listener (its future is not even running).
    let err = bind(addr, metrics, rx).await.err().expect("port in use");
    assert!(err.to_string().contains(&addr.to_string()), "{err}");
}
