//! Strider's robot model: the genome and its parameter table, the body plan and mass model,
//! the gait, the start pose, features and cells, the design brief, random generation and
//! mutation, the experiment file, and URDF export. Plain data and pure functions; no I/O beyond reading
//! files, no physics engine.

pub mod body_plan;
pub mod brief;
pub mod contact;
pub mod drawing;
pub mod experiment;
pub mod features;
pub mod fnv;
pub mod gait;
pub mod genome;
pub mod hull;
pub mod ids;
pub mod initial_designs;
pub mod inspect;
pub mod kinematics;
pub mod mass;
pub mod motor_sizing;
pub mod outcome;
pub mod params;
pub mod pose;
pub mod precheck;
pub mod reference;
pub mod rng;
pub mod urdf;
pub mod variation;
pub mod xml;

pub use body_plan::BodyPlan;
pub use brief::DesignBrief;
pub use experiment::Experiment;
pub use features::{CellIndex, FeatureGrid, Features};
pub use genome::{Controller, Genome, Morphology};
pub use ids::{CandidateId, CandidateKey, CandidateNumber, RunId, WorkerId};
pub use outcome::{
    Fall, GaitStats, InvalidReason, Outcome, Shortfall, Skate, Standing, TrialStats,
};
pub use pose::StartPose;
pub use precheck::EvalContext;
pub use variation::{MutationRates, Scheme};

/// The Strider build, with the arithmetic this CPU gives it: trials are bit-identical only
/// within one build on one kind of CPU (see docs/rapier.md), so the database records it
/// and the coordinator refuses workers of another. The build is the version, the commit
/// (`build.rs`: two commits of one version may simulate differently), the architecture,
/// the profile and any instruction-set extensions it was compiled for ([`compiled_for`]).
pub fn build_id() -> String {
    format!(
        "strider {} (commit {}, {}, {}{}{})",
        env!("CARGO_PKG_VERSION"),
        env!("STRIDER_COMMIT"),
        std::env::consts::ARCH,
        if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        },
        cpu_arithmetic().map_or(String::new(), |a| format!(", {a}")),
        compiled_for()
    )
}

/// The instruction-set extensions this build was compiled to assume beyond the
/// architecture's baseline (`RUSTFLAGS="-C target-cpu=native"` and the like), as
/// `", compiled for avx+avx2+fma"`, or nothing for a default build on x86-64 Linux (whose
/// baseline is SSE2; a target with more in its baseline, as x86-64 macOS with SSE3, names
/// those even by default). They belong in the
/// build's identity: dependencies choose their arithmetic by them at compile time (`wide`,
/// whose SIMD types rapier uses, fuses its multiply-adds only when compiled for `fma`), so
/// the same commit simulates differently (measured: a build for `x86-64-v3` changes the
/// bits of `fidelity`'s trials).
fn compiled_for() -> String {
    const EXTENSIONS: [(&str, bool); 7] = [
        ("sse3", cfg!(target_feature = "sse3")),
        ("sse4.1", cfg!(target_feature = "sse4.1")),
        ("sse4.2", cfg!(target_feature = "sse4.2")),
        ("avx", cfg!(target_feature = "avx")),
        ("avx2", cfg!(target_feature = "avx2")),
        ("fma", cfg!(target_feature = "fma")),
        ("avx512f", cfg!(target_feature = "avx512f")),
    ];
    describe_extensions(&EXTENSIONS)
}

/// `", compiled for a+b"` for the extensions that are on, or nothing if none is.
fn describe_extensions(extensions: &[(&str, bool)]) -> String {
    let on: Vec<&str> = extensions
        .iter()
        .filter(|(_, on)| *on)
        .map(|(name, _)| *name)
        .collect();
    if on.is_empty() {
        String::new()
    } else {
        format!(", compiled for {}", on.join("+"))
    }
}

/// [`build_id`] without the leading "strider ": what `--version` prints after the program's
/// name. Computed once (it asks the CPU) and kept for the program's life, as clap wants.
pub fn build_version() -> &'static str {
    static VERSION: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    VERSION.get_or_init(|| {
        let id = build_id();
        id.strip_prefix("strider ").unwrap_or(&id).to_owned()
    })
}

/// Which of the C library's versions of `sin` and `cos` this CPU runs, where that may
/// change a trial's bits: glibc picks, when the program starts, versions compiled with
/// fused multiply-add on an x86-64 CPU with FMA and AVX2 (AVX-512 CPUs have both) and plain
/// ones otherwise, and the gait and rapier's rotations call them. (The physics' matrix
/// products used to differ by the same rule, through the `matrixmultiply` crate, measured:
/// docs/rapier.md, "The same binary on another CPU"; they are fused on every CPU now.)
pub fn cpu_arithmetic() -> Option<&'static str> {
    #[cfg(target_arch = "x86_64")]
    {
        let fused = std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("avx2");
        Some(if fused {
            "fused multiply-add"
        } else {
            "separate multiply and add"
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        None
    }
}

#[cfg(test)]
mod build_id_tests {
    use super::{build_id, compiled_for, describe_extensions};

    #[test]
    fn extensions_named_only_when_on() {
        assert_eq!(
            describe_extensions(&[("sse3", false), ("avx", true), ("fma", true)]),
            ", compiled for avx+fma"
        );
        assert_eq!(describe_extensions(&[("avx", false), ("fma", false)]), "");
    }

    /// The identity carries the suffix inside its parentheses, last.
    #[test]
    fn identity_ends_with_the_extensions() {
        let id = build_id();
        assert!(id.ends_with(&format!("{})", compiled_for())), "{id}");
    }

    /// The project's own builds (CI, the README, deploy/) are default builds: on x86-64
    /// Linux they name no extension, so their identity is what it was before extensions
    /// were named. Fails if a build setting (say `.cargo/config.toml`) turns on more; set
    /// `STRIDER_EXPECT_EXTENSIONS` to run the tests of a build made for more on purpose.
    #[cfg(all(target_arch = "x86_64", target_os = "linux"))]
    #[test]
    fn a_default_linux_build_names_no_extension() {
        if std::env::var_os("STRIDER_EXPECT_EXTENSIONS").is_none() {
            assert_eq!(compiled_for(), "");
        }
    }
}
