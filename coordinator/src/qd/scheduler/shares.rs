//! How a scarce step is shared between workers: a worker keeps twice its threads in hand,
//! so without shares one of 30 threads or more would lease a whole generation of a one-run
//! experiment while the others waited. Part of the scheduler (the method below extends
//! [`Scheduler`]).

use super::*;

/// A worker's share of `demand` candidates: in proportion to its `slots` among
/// `all_slots`, rounded up so that the shares cover the demand ([`Scheduler::lease_cap`]).
pub fn fair_share(demand: usize, slots: usize, all_slots: usize) -> usize {
    if all_slots <= slots {
        return demand;
    }
    (demand * slots).div_ceil(all_slots)
}

impl Scheduler {
    /// How many more candidates `worker` (of `slots`, among `all_slots` of every worker
    /// connected) may lease now: `None` for as many as it has room for. Where the steps in
    /// hand have fewer candidates not yet answered (waiting or leased) than the workers have
    /// slots, each worker gets at most its [`fair_share`] of them, less what it holds; a
    /// worker keeps twice its threads in hand, so one of 30 threads or more would otherwise
    /// lease a whole generation of a one-run experiment while the others waited. No cap
    /// while any run can still draw initial designs (as many as asked for, up to its
    /// window). The next generations' candidates drawn ahead count only once no open step
    /// has any waiting: until then the shares are of the open steps, which go first.
    pub fn lease_cap(&self, worker: WorkerId, slots: usize, all_slots: usize) -> Option<usize> {
        let drawing_ahead = self
            .runs
            .iter()
            .all(|r| r.record.finished || r.waiting.is_empty());
        let (mut unanswered, mut held) = (0, 0);
        for (i, r) in self.runs.iter().enumerate() {
            if r.record.finished {
                continue;
            }
            if self.initial_phase(i) && r.frontier < r.draw_limit {
                return None;
            }
            let counted = if drawing_ahead {
                u64::MAX
            } else {
                r.ahead_from()
            };
            for (_, p) in r.step.range(..counted) {
                match p.state {
                    State::Resolved(_) => {}
                    State::Waiting => unanswered += 1,
                    State::Leased { worker: w, .. } => {
                        unanswered += 1;
                        held += usize::from(w == worker);
                    }
                }
            }
            // The next generation, if it may be drawn ahead and is not yet, is demand too.
            if drawing_ahead && self.may_draw_ahead(i) && r.ahead.is_none() {
                unanswered += self.experiment.run.offspring_per_generation as usize;
            }
            // Enough for every slot: the share could not bind.
            if unanswered >= all_slots {
                return None;
            }
        }
        Some(fair_share(unanswered, slots, all_slots).saturating_sub(held))
    }
}
