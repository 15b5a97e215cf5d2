//! Idle simulation threads help the thread that holds a candidate with its confirming
//! trials.
//!
//! A design feasible at the run's step is tried again on two floors, and at a finer step
//! where `[trial] confirm_substeps_factor` asks it (`trial_outcome`): trials in a fixed
//! order, the first refusal ending it, most of a late search's simulation and, run one
//! after another, the longest chain a generation waits for. When a simulation thread of
//! the same pool has nothing to do (the end of a generation, or more cores than
//! candidates), or runs a trial drawn ahead of its generation (which the open
//! generation's end matters more than), it takes the last of those trials, once free,
//! while the holder runs them from the first. The answer is the one the holder alone
//! would give, bit for bit: each trial is a function of the design and its settings, and
//! the verdict is the first refusal in the fixed order whoever ran which. A helper's trial
//! that no longer counts (an earlier one refused, or the holder panicked) is abandoned at
//! its next control step; the time it ran is the price, paid by a thread that had nothing
//! to do.
//!
//! One helper a candidate: at the defaults the holder runs the first floor and the helper
//! the second; with the finer step on, the floors (two trials) on the holder beside the
//! finer step (one trial of twice the steps) on the helper take about as long each. A
//! second helper would only run ahead of a refusal.
//!
//! Help is offered only on threads of a pool that [`install`]ed itself (the worker's
//! simulation threads); anywhere else (`fidelity`, `eval`, `verify`'s batch) the holder
//! runs every trial itself, as before.

use std::any::Any;
use std::cell::RefCell;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};

/// Work for a thread with nothing to do: one of a candidate's trials, if still unstarted.
pub type Job = Box<dyn FnOnce() + Send>;

/// A pool that runs jobs of help on its idle threads.
pub trait Offer: Send + Sync {
    /// Queues `job` if one of the pool's threads is waiting for work and no other work
    /// waits for it; whether it did.
    fn offer(&self, job: Job) -> bool;
}

thread_local! {
    static POOL: RefCell<Option<Arc<dyn Offer>>> = const { RefCell::new(None) };
}

/// Lets the trials run on this thread offer help jobs to `pool` (`None`: no longer).
pub fn install(pool: Option<Arc<dyn Offer>>) {
    POOL.with(|p| *p.borrow_mut() = pool);
}

/// Offers `job` to this thread's pool, if it has one; whether it was taken.
fn offer(job: impl FnOnce() -> Job) -> bool {
    POOL.with(|p| p.borrow().as_ref().is_some_and(|pool| pool.offer(job())))
}

/// A trial as the checks see it: `None` only when abandoned (the flag turned true).
pub type Check<C, R> = dyn Fn(&C, &AtomicBool) -> Option<R> + Send + Sync;

/// Runs `checks` in order with `run`, ending at the first result that `refuses`: its
/// index and result, or `None` when every check passed. An idle thread of this thread's
/// pool may run the last check meanwhile (the module's doc); the answer is the one this
/// thread alone would give.
pub fn first_refusal<C, R>(
    checks: Vec<C>,
    run: Arc<Check<C, R>>,
    refuses: impl Fn(&R) -> bool,
) -> Option<(usize, R)>
where
    C: Send + Sync + 'static,
    R: Send + 'static,
{
    let n = checks.len();
    let shared = Arc::new(Shared {
        slots: Mutex::new((0..n).map(|_| Slot::Open).collect()),
        checks,
        run,
        changed: Condvar::new(),
        abandon: AtomicBool::new(false),
    });
    if n > 1 {
        let helped = shared.clone();
        offer(move || Box::new(move || helped.help()));
    }
    // However this thread leaves (a refusal, or a panic in its own trial), a helper's
    // trial no longer counts.
    let _leaving = AbandonOnDrop(&shared.abandon);
    for i in 0..n {
        let result = if shared.claim(Some(i)).is_some() {
            (shared.run)(&shared.checks[i], &shared.abandon)
                .expect("nothing abandons the holder's own trial")
        } else {
            shared.wait(i)
        };
        if refuses(&result) {
            return Some((i, result));
        }
    }
    None
}

/// One candidate's checks, as the holder and its helper share them.
struct Shared<C, R> {
    checks: Vec<C>,
    run: Arc<Check<C, R>>,
    slots: Mutex<Vec<Slot<R>>>,
    changed: Condvar,
    abandon: AtomicBool,
}

enum Slot<R> {
    /// Nobody has started it.
    Open,
    /// Someone runs it.
    Running,
    /// A helper ran it.
    Done(R),
    /// A helper's trial panicked with this.
    Panicked(Box<dyn Any + Send>),
    /// Given up, or its result taken by the holder.
    Over,
}

impl<C, R> Shared<C, R> {
    fn lock(&self) -> MutexGuard<'_, Vec<Slot<R>>> {
        // Nothing panics holding it; the slots stay consistent if something did.
        self.slots.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Marks slot `i` running if it is open (`None`: the last open one); its index.
    fn claim(&self, i: Option<usize>) -> Option<usize> {
        let mut slots = self.lock();
        let i = match i {
            Some(i) => i,
            None => slots.iter().rposition(|s| matches!(s, Slot::Open))?,
        };
        if !matches!(slots[i], Slot::Open) {
            return None;
        }
        slots[i] = Slot::Running;
        Some(i)
    }

    /// A helper's job: the last check nobody has started, if it still counts.
    fn help(&self) {
        if self.abandon.load(Ordering::SeqCst) {
            return;
        }
        let Some(i) = self.claim(None) else { return };
        let ran = catch_unwind(AssertUnwindSafe(|| {
            (self.run)(&self.checks[i], &self.abandon)
        }));
        self.lock()[i] = match ran {
            Ok(Some(r)) => Slot::Done(r),
            Ok(None) => Slot::Over,
            Err(p) => Slot::Panicked(p),
        };
        self.changed.notify_all();
    }

    /// The holder waits for check `i`, which a helper runs; a helper's panic goes on in
    /// the holder, as its own trial's would have.
    fn wait(&self, i: usize) -> R {
        let mut slots = self.lock();
        while matches!(slots[i], Slot::Running) {
            slots = self
                .changed
                .wait(slots)
                .unwrap_or_else(PoisonError::into_inner);
        }
        let slot = std::mem::replace(&mut slots[i], Slot::Over);
        drop(slots);
        match slot {
            Slot::Done(r) => r,
            Slot::Panicked(p) => resume_unwind(p),
            Slot::Open | Slot::Running | Slot::Over => {
                unreachable!("a helper's check is abandoned only once its holder has left")
            }
        }
    }
}

struct AbandonOnDrop<'a>(&'a AtomicBool);

impl Drop for AbandonOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::SeqCst);
    }
}

/// What a panic carried, as the simulation threads report it.
pub fn panic_message(p: &(dyn Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU32;
    use std::sync::mpsc;
    use std::time::Duration;

    /// Long enough for anything these tests wait for; a test that waits longer has failed.
    const PATIENCE: Duration = Duration::from_secs(60);

    /// A pool of one thread that takes every job offered.
    struct OneHelper(Mutex<mpsc::Sender<Job>>);

    impl Offer for OneHelper {
        fn offer(&self, job: Job) -> bool {
            self.0.lock().unwrap().send(job).is_ok()
        }
    }

    /// `f` on this thread with a helper thread installed as its pool; the helper's
    /// thread id, once it has run every job.
    fn with_helper<T>(f: impl FnOnce() -> T) -> (T, std::thread::ThreadId) {
        let (jobs, queue) = mpsc::channel::<Job>();
        let helper = std::thread::spawn(move || {
            for job in queue {
                job();
            }
            std::thread::current().id()
        });
        install(Some(Arc::new(OneHelper(Mutex::new(jobs)))));
        let out = catch_unwind(AssertUnwindSafe(f));
        install(None);
        let id = helper.join().unwrap();
        match out {
            Ok(out) => (out, id),
            Err(p) => resume_unwind(p),
        }
    }

    /// A helper's check that runs until it is abandoned.
    fn until_abandoned(abandon: &AtomicBool) {
        let deadline = std::time::Instant::now() + PATIENCE;
        while !abandon.load(Ordering::SeqCst) {
            assert!(std::time::Instant::now() < deadline, "never abandoned");
            std::thread::yield_now();
        }
    }

    /// A one-shot signal between a check and the test.
    fn signal() -> (Mutex<mpsc::Sender<()>>, Mutex<mpsc::Receiver<()>>) {
        let (tx, rx) = mpsc::channel();
        (Mutex::new(tx), Mutex::new(rx))
    }

    #[test]
    fn without_a_pool_the_holder_runs_checks_in_order_to_the_first_refusal() {
        let ran = Arc::new(AtomicU32::new(0));
        let r = ran.clone();
        let run: Arc<Check<u32, bool>> = Arc::new(move |c: &u32, _: &AtomicBool| {
            r.fetch_or(1 << c, Ordering::SeqCst);
            Some(*c >= 1)
        });
        assert_eq!(
            first_refusal(vec![0, 1, 2, 3], run.clone(), |r| *r),
            Some((1, true))
        );
        // Checks 2 and 3 never ran.
        assert_eq!(ran.load(Ordering::SeqCst), 0b0011);
        assert_eq!(first_refusal(vec![0], run, |r| *r), None);
    }

    #[test]
    fn a_helper_runs_the_last_check_and_its_refusal_is_the_verdict() {
        // Check 0 waits until the helper has finished check 2, so the holder finds it done.
        let (finished, wait_finished) = signal();
        let ran_on = Arc::new(Mutex::new(Vec::new()));
        let record = ran_on.clone();
        let run: Arc<Check<u32, bool>> = Arc::new(move |c: &u32, _: &AtomicBool| {
            record
                .lock()
                .unwrap()
                .push((*c, std::thread::current().id()));
            match c {
                0 => {
                    wait_finished
                        .lock()
                        .unwrap()
                        .recv_timeout(PATIENCE)
                        .unwrap();
                    Some(false)
                }
                2 => {
                    finished.lock().unwrap().send(()).unwrap();
                    Some(true)
                }
                _ => Some(false),
            }
        });
        let holder = std::thread::current().id();
        let (verdict, helper) = with_helper(|| first_refusal(vec![0, 1, 2], run, |r| *r));
        assert_eq!(verdict, Some((2, true)));
        let mut ran_on = ran_on.lock().unwrap().clone();
        ran_on.sort_by_key(|(c, _)| *c);
        assert_eq!(ran_on, vec![(0, holder), (1, holder), (2, helper)]);
    }

    /// Two checks: the holder's (0) waits until the helper has started check 1, then
    /// gives `holder()`; the helper's runs until abandoned. Also whether it was.
    fn holder_beside_a_helper_until_abandoned(
        holder: fn() -> Option<bool>,
    ) -> (Arc<Check<u32, bool>>, Arc<AtomicBool>) {
        let (started, wait_started) = signal();
        let abandoned = Arc::new(AtomicBool::new(false));
        let seen = abandoned.clone();
        let run: Arc<Check<u32, bool>> = Arc::new(move |c: &u32, abandon: &AtomicBool| {
            if *c == 0 {
                wait_started.lock().unwrap().recv_timeout(PATIENCE).unwrap();
                return holder();
            }
            started.lock().unwrap().send(()).unwrap();
            until_abandoned(abandon);
            seen.store(true, Ordering::SeqCst);
            None
        });
        (run, abandoned)
    }

    #[test]
    fn a_helpers_check_is_abandoned_when_an_earlier_one_refuses() {
        let (run, abandoned) = holder_beside_a_helper_until_abandoned(|| Some(true));
        let (verdict, _) = with_helper(|| first_refusal(vec![0, 1], run, |r| *r));
        assert_eq!(verdict, Some((0, true)));
        assert!(
            abandoned.load(Ordering::SeqCst),
            "the helper's check was abandoned"
        );
    }

    #[test]
    fn a_panic_in_the_helpers_check_goes_on_in_the_holder() {
        let (finished, wait_finished) = signal();
        let run: Arc<Check<u32, bool>> = Arc::new(move |c: &u32, _: &AtomicBool| {
            if *c == 0 {
                wait_finished
                    .lock()
                    .unwrap()
                    .recv_timeout(PATIENCE)
                    .unwrap();
                return Some(false);
            }
            finished.lock().unwrap().send(()).unwrap();
            panic!("contact manifold overflow");
        });
        let caught = catch_unwind(AssertUnwindSafe(|| {
            with_helper(|| first_refusal(vec![0, 1], run, |r| *r))
        }))
        .unwrap_err();
        assert_eq!(panic_message(&*caught), "contact manifold overflow");
    }

    #[test]
    fn a_panic_in_the_holders_check_abandons_the_helpers() {
        let (run, abandoned) =
            holder_beside_a_helper_until_abandoned(|| panic!("non-finite velocity"));
        let caught = catch_unwind(AssertUnwindSafe(|| {
            with_helper(|| first_refusal(vec![0, 1], run, |r| *r))
        }))
        .unwrap_err();
        assert_eq!(panic_message(&*caught), "non-finite velocity");
        assert!(
            abandoned.load(Ordering::SeqCst),
            "the helper's check was abandoned"
        );
    }
}
