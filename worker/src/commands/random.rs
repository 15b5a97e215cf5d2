//! `random`: the random genome a run draws as candidate N.

use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::{Genome, Scheme};
use strider_process::outln;

/// Arguments of `random`.
#[derive(clap::Args)]
pub struct RandomArgs {
    /// Run seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Candidate number.
    #[arg(long, default_value_t = 0)]
    candidate: u64,
    /// Scheme (GENOME also draws a random controller).
    #[arg(long, default_value = "static")]
    scheme: Scheme,
}

/// Prints the genome as JSON.
pub fn execute(args: RandomArgs) -> anyhow::Result<()> {
    let RandomArgs {
        seed,
        candidate,
        scheme,
    } = args;
    let mut rng = CandidateSeed::new(seed, candidate).rng(Purpose::RandomGenome);
    outln!("{}", Genome::random(scheme, &mut rng).to_json_pretty());
    Ok(())
}
