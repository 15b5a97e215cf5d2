//! `strider.v1.ClientService`: progress (now, and as a stream) and the library, read from
//! the scheduler and the database.

use super::Shared;
use crate::db::{EliteFilter, StoredElite};
use std::hash::{BuildHasher, Hash, Hasher};
use std::pin::Pin;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;
use strider_common::RunId;
use strider_proto::convert::scheme_to_wire;
use strider_proto::v1::{self, client_service_server::ClientService};
use strider_proto::PROTOCOL_VERSION;
use tonic::{Request, Response, Status};

/// Largest page of elites.
pub const MAX_PAGE: u32 = 1000;

/// The client service.
pub struct ClientApi {
    pub(crate) shared: Arc<Shared>,
}

fn check_version(v: u32) -> Result<(), Status> {
    if v == PROTOCOL_VERSION {
        Ok(())
    } else {
        Err(Status::failed_precondition(format!(
            "protocol version mismatch: the client speaks version {v}, this coordinator version {PROTOCOL_VERSION}"
        )))
    }
}

/// Page tokens: the next page's offset and a tag, a hash keyed per coordinator process of
/// the offset and the request's filter, so that a token this process did not issue for
/// this query (forged, edited, or from another query) is refused, as AIP-158 asks. A
/// restarted coordinator refuses the old process's tokens: list again from the start.
fn page_key() -> &'static std::collections::hash_map::RandomState {
    static KEY: std::sync::OnceLock<std::collections::hash_map::RandomState> =
        std::sync::OnceLock::new();
    KEY.get_or_init(Default::default)
}

fn page_tag(offset: u64, filter: &EliteFilter, size: u32) -> u64 {
    let mut h = page_key().build_hasher();
    offset.hash(&mut h);
    filter.run.hash(&mut h);
    filter.cell.hash(&mut h);
    filter.min_fitness.map(f64::to_bits).hash(&mut h);
    size.hash(&mut h);
    h.finish()
}

fn page_token(offset: u64, filter: &EliteFilter, size: u32) -> String {
    format!("{offset:x}.{:016x}", page_tag(offset, filter, size))
}

fn page_offset(token: &str, filter: &EliteFilter, size: u32) -> Result<u64, Status> {
    let refused = || {
        Status::invalid_argument(format!(
            "page_token: {token:?} is not a token this coordinator issued for this query \
             (tokens hold for one coordinator process and one set of filters and page size)"
        ))
    };
    let (offset, tag) = token.split_once('.').ok_or_else(refused)?;
    let offset = u64::from_str_radix(offset, 16).map_err(|_| refused())?;
    let tag = u64::from_str_radix(tag, 16).map_err(|_| refused())?;
    if tag == page_tag(offset, filter, size) {
        Ok(offset)
    } else {
        Err(refused())
    }
}

fn db_error(e: crate::db::DbError) -> Status {
    Status::internal(format!("reading the database: {e}"))
}

/// Progress now, as sent on the wire.
pub fn progress(shared: &Shared) -> v1::Progress {
    let (name, runs, settings) = shared.with(false, |s| {
        (
            s.experiment().name.clone(),
            s.progress(),
            s.experiment().run,
        )
    });
    let generations = settings.generations;
    let fraction_done = crate::qd::scheduler::fraction_done(&runs, &settings);
    v1::Progress {
        experiment: name,
        runs: runs
            .into_iter()
            .map(|r| v1::RunProgress {
                run: r.run.0,
                scheme: scheme_to_wire(r.scheme).into(),
                repeat: r.repeat,
                seed: r.seed.0,
                generation: r.generation,
                generations,
                initial_passed: r.initial_passed,
                trials_done: r.trials_done,
                trials_pending: r.trials_pending,
                coverage: r.library.coverage,
                best_fitness: r.library.max_fitness,
                mean_fitness: r.library.mean_fitness,
                qd_score: r.library.qd_score,
                finished: r.finished,
                feasible_elites: r.library.elites as u32,
                infeasible_elites: r.library.infeasible_elites as u32,
                infeasible_only: r.library.infeasible_only as u32,
            })
            .collect(),
        workers_connected: shared.workers.load(Ordering::Relaxed),
        trials_per_second: shared
            .throughput
            .lock()
            .expect("no panic while counting")
            .rate(shared.running_seconds()),
        fraction_done,
        eta_seconds: shared.eta(fraction_done),
    }
}

fn summary(e: &StoredElite) -> v1::EliteSummary {
    let features = match &e.outcome {
        strider_common::Outcome::Valid { features, .. } => features.0.to_vec(),
        _ => Vec::new(),
    };
    v1::EliteSummary {
        run: e.run.0,
        cell: e.cell.0,
        candidate: e.candidate.0,
        fitness: e.fitness,
        features,
    }
}

#[tonic::async_trait]
impl ClientService for ClientApi {
    async fn get_progress(
        &self,
        request: Request<v1::ProgressRequest>,
    ) -> Result<Response<v1::Progress>, Status> {
        check_version(request.get_ref().protocol_version)?;
        Ok(Response::new(progress(&self.shared)))
    }

    type WatchProgressStream =
        Pin<Box<dyn tokio_stream::Stream<Item = Result<v1::Progress, Status>> + Send>>;

    async fn watch_progress(
        &self,
        request: Request<v1::WatchProgressRequest>,
    ) -> Result<Response<Self::WatchProgressStream>, Status> {
        let r = request.get_ref();
        check_version(r.protocol_version)?;
        if !r.interval_seconds.is_finite() || r.interval_seconds < 0.0 {
            return Err(Status::invalid_argument(format!(
                "interval_seconds: {} is not a duration",
                r.interval_seconds
            )));
        }
        let interval = Duration::from_secs_f64(r.interval_seconds.clamp(0.1, 3600.0));
        let shared = self.shared.clone();
        let mut steps = shared.steps.subscribe();
        let mut finished = shared.finished.subscribe();
        let (tx, rx) = tokio::sync::mpsc::channel(4);
        tokio::spawn(async move {
            loop {
                steps.borrow_and_update();
                let done = *finished.borrow_and_update();
                if tx.send(Ok(progress(&shared))).await.is_err() || done {
                    return;
                }
                tokio::time::sleep(interval).await;
                tokio::select! {
                    r = steps.changed() => if r.is_err() { return },
                    r = finished.changed() => if r.is_err() { return },
                    _ = tx.closed() => return,
                }
            }
        });
        Ok(Response::new(Box::pin(
            tokio_stream::wrappers::ReceiverStream::new(rx),
        )))
    }

    async fn list_elites(
        &self,
        request: Request<v1::ListElitesRequest>,
    ) -> Result<Response<v1::ListElitesResponse>, Status> {
        let r = request.get_ref();
        check_version(r.protocol_version)?;
        let size = match r.page_size {
            0 => 100,
            n if n <= MAX_PAGE => n,
            n => {
                return Err(Status::invalid_argument(format!(
                    "page_size: {n} is above {MAX_PAGE}"
                )))
            }
        };
        if let Some(f) = r.min_fitness {
            if !f.is_finite() {
                return Err(Status::invalid_argument(format!(
                    "min_fitness: {f} is not a finite number"
                )));
            }
        }
        let filter = EliteFilter {
            run: r.run.map(RunId),
            cell: r.cell.map(i64::from),
            min_fitness: r.min_fitness,
        };
        let offset = if r.page_token.is_empty() {
            0
        } else {
            page_offset(&r.page_token, &filter, size)?
        };
        // One more than asked, to know whether another page follows.
        let mut rows = self
            .shared
            .db
            .list_elites(&filter, offset, size + 1)
            .await
            .map_err(db_error)?;
        let more = rows.len() > size as usize;
        rows.truncate(size as usize);
        Ok(Response::new(v1::ListElitesResponse {
            next_page_token: if more {
                page_token(offset + u64::from(size), &filter, size)
            } else {
                String::new()
            },
            elites: rows.iter().map(summary).collect(),
        }))
    }

    async fn get_elite(
        &self,
        request: Request<v1::GetEliteRequest>,
    ) -> Result<Response<v1::Elite>, Status> {
        let r = request.get_ref();
        check_version(r.protocol_version)?;
        let filter = EliteFilter {
            run: Some(RunId(r.run)),
            cell: Some(i64::from(r.cell)),
            min_fitness: None,
        };
        let e = self
            .shared
            .db
            .list_elites(&filter, 0, 1)
            .await
            .map_err(db_error)?
            .pop()
            .ok_or_else(|| {
                Status::not_found(format!("run {} has no elite in cell {}", r.run, r.cell))
            })?;
        Ok(Response::new(v1::Elite {
            summary: Some(summary(&e)),
            genome: Some((&e.genome).into()),
            outcome: Some((&e.outcome).into()),
        }))
    }
}
