//! `status`: a running coordinator's progress, over gRPC, as a table or JSON.

use super::Exit;
use anyhow::Context;
use std::path::PathBuf;
use std::time::Duration;
use strider_process::outln;
use strider_proto::secret::{client_interceptor, Secret};
use strider_proto::v1::client_service_client::ClientServiceClient;

/// Arguments of `status`.
#[derive(clap::Args)]
pub struct StatusArgs {
    /// The coordinator, e.g. http://host:50051.
    #[arg(long)]
    connect: String,
    /// File holding the shared secret (else the STRIDER_SECRET environment variable).
    #[arg(long)]
    token_file: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// Prints the coordinator's progress.
pub async fn execute(args: StatusArgs) -> anyhow::Result<Exit> {
    let secret = Secret::load(args.token_file.as_deref())?;
    let url = args.connect.as_str();
    let channel = tonic::transport::Endpoint::from_shared(url.to_string())
        .with_context(|| format!("coordinator URL {url}"))?
        .connect_timeout(Duration::from_secs(5))
        .connect()
        .await
        .with_context(|| format!("connecting to {url}"))?;
    let mut client =
        ClientServiceClient::with_interceptor(channel, client_interceptor(Some(&secret)));
    let p = client
        .get_progress(strider_proto::v1::ProgressRequest {
            protocol_version: strider_proto::PROTOCOL_VERSION,
        })
        .await
        .map_err(|s| anyhow::anyhow!("{url}: {} ({:?})", s.message(), s.code()))?
        .into_inner();
    if args.json {
        let runs: Vec<_> = p.runs.iter().map(|r| serde_json::json!({
            "run": r.run, "scheme": strider_proto::convert::scheme_from_wire(r.scheme).map(|s| s.name()).unwrap_or("?"),
            "repeat": r.repeat, "seed": r.seed, "generation": r.generation, "generations": r.generations,
            "initial_passed": r.initial_passed, "trials_done": r.trials_done, "trials_pending": r.trials_pending,
            "coverage": r.coverage, "best_fitness": r.best_fitness, "mean_fitness": r.mean_fitness,
            "qd_score": r.qd_score, "finished": r.finished,
            "feasible_elites": r.feasible_elites, "infeasible_elites": r.infeasible_elites,
            "infeasible_only": r.infeasible_only,
        })).collect();
        outln!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "experiment": p.experiment, "workers_connected": p.workers_connected,
                "trials_per_second": p.trials_per_second, "fraction_done": p.fraction_done,
                "eta_seconds": p.eta_seconds, "runs": runs,
            }))?
        );
        return Ok(Exit::Success);
    }
    outln!(
        "experiment `{}`: {} workers connected, {:.1} trials/s over the last minute; {:.1} % done{}",
        p.experiment,
        p.workers_connected,
        p.trials_per_second,
        100.0 * p.fraction_done,
        match p.eta_seconds {
            Some(s) => format!(", about {} left", strider_process::duration_words(s)),
            None => String::new(),
        }
    );
    outln!("run  scheme   repeat  generation        initial  candidates pending  feasible  infeasible only  coverage  best      mean      QD score");
    for r in &p.runs {
        let scheme = strider_proto::convert::scheme_from_wire(r.scheme)
            .map(|s| s.name())
            .unwrap_or("?");
        let generation = if r.finished {
            format!("{}/{} done", r.generation, r.generations)
        } else {
            format!("{}/{}", r.generation, r.generations)
        };
        outln!(
            "{:<4} {:<8} {:<7} {:<17} {:<8} {:<10} {:<8} {:<9} {:<16} {:<9} {:<9.4} {:<9.4} {:.2}",
            r.run,
            scheme,
            r.repeat,
            generation,
            r.initial_passed,
            r.trials_done,
            r.trials_pending,
            r.feasible_elites,
            r.infeasible_only,
            format!("{:.2} %", 100.0 * r.coverage),
            r.best_fitness,
            r.mean_fitness,
            r.qd_score
        );
    }
    Ok(Exit::Success)
}
