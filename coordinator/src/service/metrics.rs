//! An optional Prometheus endpoint (`serve --metrics ADDR`): `GET /metrics` answers the
//! progress of every run in Prometheus' text format. Plain HTTP/1.1 without the secret:
//! it carries only aggregate numbers, and it is off unless asked for, on the address
//! the operator chooses.

use super::client_api::progress;
use super::Shared;
use std::fmt::Write as _;
use std::sync::Arc;
use std::time::Duration;
use strider_proto::v1;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// Longest request head read (a scrape's is a few hundred bytes).
const MAX_REQUEST_BYTES: usize = 8192;

/// A per-run metric: name, type, help, and how to read it.
type RunFamily = (
    &'static str,
    &'static str,
    &'static str,
    fn(&v1::RunProgress) -> f64,
);

/// The metrics of `p`, in Prometheus' text exposition format (version 0.0.4).
pub fn render(p: &v1::Progress, results_total: u64) -> String {
    let mut out = String::new();
    let run_families: [RunFamily; 8] = [
        (
            "run_generation",
            "gauge",
            "Last completed generation of the run.",
            |r| f64::from(r.generation),
        ),
        (
            "run_trials_done_total",
            "counter",
            "Candidates of the run evaluated.",
            |r| r.trials_done as f64,
        ),
        (
            "run_trials_pending",
            "gauge",
            "Candidates of the run's current step not yet evaluated.",
            |r| r.trials_pending as f64,
        ),
        (
            "run_coverage",
            "gauge",
            "Share of the run's cells holding an elite.",
            |r| r.coverage,
        ),
        (
            "run_best_fitness",
            "gauge",
            "Best fitness in the run's library.",
            |r| r.best_fitness,
        ),
        (
            "run_mean_fitness",
            "gauge",
            "Mean fitness of the run's elites.",
            |r| r.mean_fitness,
        ),
        (
            "run_qd_score",
            "gauge",
            "Sum of the run's elite fitness.",
            |r| r.qd_score,
        ),
        (
            "run_finished",
            "gauge",
            "1 when the run has done all its generations.",
            |r| f64::from(u8::from(r.finished)),
        ),
    ];
    let head = |out: &mut String, name: &str, kind: &str, help: &str| {
        let _ = writeln!(
            out,
            "# HELP strider_{name} {help}\n# TYPE strider_{name} {kind}"
        );
    };
    head(
        &mut out,
        "results_total",
        "counter",
        "Results accepted since the coordinator started.",
    );
    let _ = writeln!(out, "strider_results_total {results_total}");
    head(
        &mut out,
        "results_per_second",
        "gauge",
        "Results accepted per second over the last minute.",
    );
    let _ = writeln!(out, "strider_results_per_second {}", p.trials_per_second);
    head(
        &mut out,
        "workers_connected",
        "gauge",
        "Worker connections now.",
    );
    let _ = writeln!(out, "strider_workers_connected {}", p.workers_connected);
    head(
        &mut out,
        "fraction_done",
        "gauge",
        "Share of every run's candidates done (initial population and generations), 0 to 1.",
    );
    let _ = writeln!(out, "strider_fraction_done {}", p.fraction_done);
    if let Some(eta) = p.eta_seconds {
        head(
            &mut out,
            "eta_seconds",
            "gauge",
            "Estimated seconds to the end of the experiment, at this coordinator's pace so far.",
        );
        let _ = writeln!(out, "strider_eta_seconds {eta}");
    }
    for (name, kind, help, value) in run_families {
        head(&mut out, name, kind, help);
        for r in &p.runs {
            let scheme = v1::Scheme::try_from(r.scheme)
                .map(|s| s.as_str_name().trim_start_matches("SCHEME_").to_lowercase())
                .unwrap_or_else(|_| "unknown".into());
            let _ = writeln!(
                out,
                "strider_{name}{{run=\"{}\",scheme=\"{scheme}\",repeat=\"{}\"}} {}",
                r.run,
                r.repeat,
                value(r)
            );
        }
    }
    out
}

/// Answers scrapes on `listener` until the task is dropped.
pub async fn serve_metrics(listener: TcpListener, shared: Arc<Shared>) {
    // A failed accept (out of file descriptors) is retried after a wait, not at once.
    let mut backoff = super::incoming::AcceptBackoff::default();
    loop {
        let stream = match listener.accept().await {
            Ok((stream, _)) => {
                backoff.succeeded();
                stream
            }
            Err(e) => {
                tokio::time::sleep(backoff.failed(&e)).await;
                continue;
            }
        };
        let shared = shared.clone();
        tokio::spawn(async move {
            // A client that sends nothing does not hold a task for ever.
            let _ = tokio::time::timeout(Duration::from_secs(10), answer(stream, &shared)).await;
        });
    }
}

async fn answer(mut stream: TcpStream, shared: &Shared) -> std::io::Result<()> {
    let mut head = Vec::new();
    let mut buf = [0u8; 1024];
    while !head.windows(4).any(|w| w == b"\r\n\r\n") {
        let n = stream.read(&mut buf).await?;
        if n == 0 || head.len() + n > MAX_REQUEST_BYTES {
            return Ok(());
        }
        head.extend_from_slice(&buf[..n]);
    }
    let line = String::from_utf8_lossy(&head);
    let mut words = line.split_whitespace();
    let (status, body) = match (words.next(), words.next()) {
        (Some("GET"), Some("/metrics")) => {
            ("200 OK", render(&progress(shared), shared.results_total()))
        }
        (Some("GET"), Some(_)) => (
            "404 Not Found",
            "only /metrics is served here\n".to_string(),
        ),
        _ => (
            "405 Method Not Allowed",
            "only GET /metrics is served here\n".to_string(),
        ),
    };
    let response = format!(
        "HTTP/1.1 {status}\r\nContent-Type: text/plain; version=0.0.4; charset=utf-8\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    stream.write_all(response.as_bytes()).await?;
    stream.shutdown().await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_family_is_declared_once_and_every_run_has_a_labelled_sample() {
        let run = |i: u32, scheme: v1::Scheme| v1::RunProgress {
            run: i,
            scheme: scheme.into(),
            repeat: 0,
            generation: 7,
            trials_done: 500,
            coverage: 0.25,
            best_fitness: 1.5,
            finished: i == 1,
            ..Default::default()
        };
        let p = v1::Progress {
            experiment: "e".into(),
            runs: vec![run(0, v1::Scheme::Static), run(1, v1::Scheme::Es)],
            workers_connected: 3,
            trials_per_second: 12.5,
            fraction_done: 0.5,
            eta_seconds: Some(60.0),
        };
        let text = render(&p, 1234);
        assert!(text.contains("\nstrider_fraction_done 0.5\n"), "{text}");
        assert!(text.contains("\nstrider_eta_seconds 60\n"), "{text}");
        assert!(text.contains("\nstrider_results_total 1234\n"), "{text}");
        assert!(text.contains("\nstrider_workers_connected 3\n"), "{text}");
        assert!(
            text.contains("\nstrider_run_generation{run=\"0\",scheme=\"static\",repeat=\"0\"} 7\n"),
            "{text}"
        );
        assert!(
            text.contains("\nstrider_run_coverage{run=\"1\",scheme=\"es\",repeat=\"0\"} 0.25\n"),
            "{text}"
        );
        assert!(
            text.contains("\nstrider_run_finished{run=\"1\",scheme=\"es\",repeat=\"0\"} 1\n"),
            "{text}"
        );
        let types: Vec<&str> = text.lines().filter(|l| l.starts_with("# TYPE")).collect();
        let mut unique = types.clone();
        unique.dedup();
        assert_eq!(types.len(), unique.len());
        assert_eq!(types.len(), 13);
        // Every sample line is `name{labels} value` or `name value` with a number.
        for l in text.lines().filter(|l| !l.starts_with('#')) {
            let value = l.rsplit(' ').next().unwrap();
            assert!(value.parse::<f64>().is_ok(), "{l}");
        }
    }
}
