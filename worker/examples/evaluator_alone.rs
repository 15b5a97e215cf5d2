//! The yardstick for `run`'s efficiency (BENCHMARKS.md): evaluates every candidate that a
//! finished `run` simulated, again, with the batch evaluator alone (no coordinator, no
//! gRPC, no database), and prints the trials per second.
//!
//! `cargo run --release -p strider-worker --example evaluator_alone -- DB [THREADS]`

use sqlx::sqlite::SqliteConnectOptions;
use sqlx::{ConnectOptions, Row};
use std::num::NonZeroUsize;
use std::str::FromStr;
use std::time::Instant;
use strider_common::ids::CandidateNumber;
use strider_common::precheck::precheck;
use strider_common::rng::{CandidateSeed, RunSeed};
use strider_common::EvalContext;
use strider_common::{Experiment, Genome, Scheme};
use strider_process::default_threads;
use strider_worker::batch::{evaluate_batch, Job};

#[tokio::main(flavor = "current_thread")]
async fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let db = args.get(1).expect("usage: evaluator_alone DB [THREADS]");
    let threads = match args.get(2) {
        Some(t) => NonZeroUsize::from_str(t)?,
        None => default_threads(),
    };
    let mut con = SqliteConnectOptions::from_str(&format!("sqlite://{db}"))?
        .read_only(true)
        .connect()
        .await?;
    let definition: String = sqlx::query("SELECT definition FROM experiment")
        .fetch_one(&mut con)
        .await?
        .get(0);
    let experiment: Experiment = toml::from_str(&definition)?;
    let ctx = EvalContext::of(&experiment);
    let mut jobs = Vec::new();
    for r in sqlx::query(
        "SELECT r.scheme, r.seed, c.number, c.genome FROM candidates c \
         JOIN runs r ON r.id = c.run_id ORDER BY c.run_id, c.number",
    )
    .fetch_all(&mut con)
    .await?
    {
        let scheme = Scheme::from_str(&r.get::<String, _>(0)).map_err(anyhow::Error::msg)?;
        let genome: Genome = serde_json::from_str(&r.get::<String, _>(3))?;
        // What the coordinator settles itself never reaches an evaluator.
        if precheck(&ctx, &genome, scheme).is_some() {
            continue;
        }
        jobs.push(Job {
            genome,
            scheme,
            seed: CandidateSeed {
                run: RunSeed(r.get::<i64, _>(1) as u64),
                candidate: CandidateNumber(r.get::<i64, _>(2) as u64),
            },
            to_beat: None,
        });
    }
    let started = Instant::now();
    let outcomes = evaluate_batch(&ctx, &jobs, threads);
    let seconds = started.elapsed().as_secs_f64();
    println!(
        "{} trials on {threads} threads in {seconds:.2} s: {:.1} trials/s",
        outcomes.len(),
        outcomes.len() as f64 / seconds
    );
    Ok(())
}
