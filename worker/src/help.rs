//! Idle simulation threads help the thread that holds a candidate with its confirming
//! trials.
//!
//! A design feasible at the run's step is tried again on two floors and at the finer step
//! (`trial_outcome`): three trials in a fixed order, the first refusal ending it, about
//! four fifths of a late search's simulation and, run one after another, the longest
//! chain a generation waits for. When a simulation thread of the same worker is idle (the
//! end of a generation, or more cores than candidates), it takes the last of those trials
//! that nobody has started while the holder runs them from the first. The answer is the
//! one the holder alone would give, bit for bit: each trial is a function of the design
//! and its settings, and the first refusal in the fixed order is the verdict whoever ran
//! which. A helper's trial that no longer counts (an earlier one refused) is abandoned at
//! its next control step.
//!
//! Threads offer help only where [`Helpers::install`] was called (the worker's simulation
//! threads); anywhere else (`fidelity`, `eval`, `verify`'s batch) a holder runs every
//! trial itself, as before.

use std::cell::RefCell;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};

/// Work for an idle thread: one of a candidate's trials, if still unstarted.
pub type Job = Box<dyn FnOnce() + Send>;

/// A pool's offer of help: where jobs go, and how many of its threads wait for work.
#[derive(Clone)]
pub struct Helpers {
    jobs: flume::Sender<Job>,
    idle: Arc<AtomicUsize>,
}

thread_local! {
    static HELPERS: RefCell<Option<Helpers>> = const { RefCell::new(None) };
}

impl Helpers {
    /// A pool's helpers and the queue its threads take jobs from.
    pub fn new() -> (Self, flume::Receiver<Job>) {
        let (jobs, queue) = flume::unbounded();
        let idle = Arc::new(AtomicUsize::new(0));
        (Self { jobs, idle }, queue)
    }

    /// Lets the trials run on this thread offer jobs to the pool's idle threads.
    pub fn install(self) {
        HELPERS.with(|h| *h.borrow_mut() = Some(self));
    }

    /// Runs `wait` (a thread waiting for work) counted as idle.
    pub fn idle_while<T>(&self, wait: impl FnOnce() -> T) -> T {
        self.idle.fetch_add(1, Ordering::SeqCst);
        let got = wait();
        self.idle.fetch_sub(1, Ordering::SeqCst);
        got
    }
}

/// Hands up to `wanted` jobs from `job` to this thread's pool, as many as it has threads
/// waiting for work; how many were handed.
fn offer(wanted: usize, job: impl Fn() -> Job) -> usize {
    HELPERS.with(|h| {
        let h = h.borrow();
        let Some(h) = h.as_ref() else { return 0 };
        let n = wanted.min(h.idle.load(Ordering::SeqCst));
        for _ in 0..n {
            // The receiver lives as long as the pool's threads, one of which is this one.
            let _ = h.jobs.send(job());
        }
        n
    })
}

/// A trial as the checks see it: `None` only when abandoned (the flag turned true).
pub type Check<C, R> = dyn Fn(&C, &AtomicBool) -> Option<R> + Send + Sync;

/// Runs `checks` in order with `run`, ending at the first result that `refuses`: its
/// index and result, or `None` when every check passed. Idle threads of this thread's
/// pool may run the later checks meanwhile (the module's doc); the answer is the one this
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
        offer(n - 1, || {
            let shared = shared.clone();
            Box::new(move || shared.help())
        });
    }
    // However this thread leaves (a refusal, or a panic in its own trial), a helper's
    // trial no longer counts.
    let _leaving = AbandonOnDrop(&shared.abandon);
    for i in 0..n {
        let result = if shared.claim(|_| Some(i)).is_some() {
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

/// One candidate's checks, as the holder and its helpers share them.
struct Shared<C, R> {
    checks: Vec<C>,
    run: Arc<Check<C, R>>,
    slots: Mutex<Vec<Slot<R>>>,
    changed: Condvar,
    abandon: AtomicBool,
}

enum Slot<R> {
    Open,
    Running,
    Done(R),
    Panicked(String),
    Abandoned,
}

impl<C, R> Shared<C, R> {
    /// Marks the slot `pick` chooses among the open ones running; its index.
    fn claim(&self, pick: impl Fn(&[usize]) -> Option<usize>) -> Option<usize> {
        let mut slots = self
            .slots
            .lock()
            .expect("no thread panics holding the slots");
        let open: Vec<usize> = (0..slots.len())
            .filter(|&i| matches!(slots[i], Slot::Open))
            .collect();
        let i = pick(&open).filter(|i| open.contains(i))?;
        slots[i] = Slot::Running;
        Some(i)
    }

    /// A helper's job: the last check nobody has started, if any.
    fn help(&self) {
        if self.abandon.load(Ordering::SeqCst) {
            return;
        }
        let Some(i) = self.claim(|open| open.last().copied()) else {
            return;
        };
        let ran = catch_unwind(AssertUnwindSafe(|| {
            (self.run)(&self.checks[i], &self.abandon)
        }));
        let slot = match ran {
            Ok(Some(r)) => Slot::Done(r),
            Ok(None) => Slot::Abandoned,
            Err(p) => Slot::Panicked(panic_message(&*p)),
        };
        self.slots
            .lock()
            .expect("no thread panics holding the slots")[i] = slot;
        self.changed.notify_all();
    }

    /// The holder waits for check `i`, which a helper runs.
    fn wait(&self, i: usize) -> R {
        let mut slots = self
            .slots
            .lock()
            .expect("no thread panics holding the slots");
        while matches!(slots[i], Slot::Running) {
            slots = self
                .changed
                .wait(slots)
                .expect("no thread panics holding the slots");
        }
        match std::mem::replace(&mut slots[i], Slot::Abandoned) {
            Slot::Done(r) => r,
            // As the holder's own trial would have panicked.
            Slot::Panicked(message) => panic!("{message}"),
            Slot::Open | Slot::Running | Slot::Abandoned => {
                unreachable!("a check is abandoned only once its holder has left")
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
pub fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU32;

    /// Checks that pass unless their number is in `refusing`, recording who ran them.
    fn counting(refusing: &'static [u32]) -> (Arc<Check<u32, bool>>, Arc<AtomicU32>) {
        let ran = Arc::new(AtomicU32::new(0));
        let r = ran.clone();
        let run: Arc<Check<u32, bool>> = Arc::new(move |c: &u32, _: &AtomicBool| {
            r.fetch_or(1 << c, Ordering::SeqCst);
            Some(refusing.contains(c))
        });
        (run, ran)
    }

    #[test]
    fn without_helpers_the_holder_runs_checks_in_order_to_the_first_refusal() {
        let (run, ran) = counting(&[1, 2]);
        assert_eq!(
            first_refusal(vec![0, 1, 2, 3], run, |r| *r),
            Some((1, true))
        );
        // Checks 2 and 3 never ran.
        assert_eq!(ran.load(Ordering::SeqCst), 0b0011);
        let (run, ran) = counting(&[]);
        assert_eq!(first_refusal(vec![0, 1, 2], run, |r| *r), None);
        assert_eq!(ran.load(Ordering::SeqCst), 0b0111);
    }

    #[test]
    fn a_helper_takes_the_last_open_check_and_the_holder_uses_its_result() {
        let (run, ran) = counting(&[2]);
        let shared = Arc::new(Shared {
            checks: vec![0u32, 1, 2],
            run,
            slots: Mutex::new((0..3).map(|_| Slot::Open).collect()),
            changed: Condvar::new(),
            abandon: AtomicBool::new(false),
        });
        let helper = shared.clone();
        std::thread::spawn(move || helper.help()).join().unwrap();
        assert_eq!(ran.load(Ordering::SeqCst), 0b100);
        // The holder runs 0 and 1 and takes 2's refusal from the helper.
        for i in 0..2 {
            assert_eq!(shared.claim(|_| Some(i)), Some(i));
        }
        assert_eq!(shared.claim(|_| Some(2)), None, "2 is the helper's");
        assert!(shared.wait(2));
    }

    /// A thread of a pool of one, waiting for work: `helpers` counts it idle on return.
    fn helper_thread(
        helpers: &Helpers,
        queue: flume::Receiver<Job>,
    ) -> std::thread::JoinHandle<()> {
        let h = helpers.clone();
        let t = std::thread::spawn(move || h.idle_while(|| queue.recv()).unwrap()());
        while helpers.idle.load(Ordering::SeqCst) == 0 {
            std::thread::yield_now();
        }
        t
    }

    #[test]
    fn an_idle_thread_runs_a_later_check_abandoned_when_an_earlier_one_refuses() {
        let (helpers, queue) = Helpers::new();
        let t = helper_thread(&helpers, queue);
        helpers.install();
        let (started, start) = std::sync::mpsc::channel::<()>();
        let (started, start) = (Mutex::new(started), Mutex::new(start));
        let abandoned = Arc::new(AtomicBool::new(false));
        let seen = abandoned.clone();
        let run: Arc<Check<u32, bool>> = Arc::new(move |c: &u32, abandon: &AtomicBool| {
            if *c == 0 {
                // The holder refuses once the helper has started check 1.
                start.lock().unwrap().recv().unwrap();
                return Some(true);
            }
            started.lock().unwrap().send(()).unwrap();
            while !abandon.load(Ordering::SeqCst) {
                std::thread::yield_now();
            }
            seen.store(true, Ordering::SeqCst);
            None
        });
        assert_eq!(first_refusal(vec![0, 1], run, |r| *r), Some((0, true)));
        t.join().unwrap();
        assert!(
            abandoned.load(Ordering::SeqCst),
            "the helper's check was abandoned"
        );
        HELPERS.with(|h| *h.borrow_mut() = None);
    }

    #[test]
    fn a_panic_in_a_helpers_check_reaches_the_holder() {
        let (helpers, queue) = Helpers::new();
        let t = helper_thread(&helpers, queue);
        helpers.install();
        let (started, start) = std::sync::mpsc::channel::<()>();
        let (started, start) = (Mutex::new(started), Mutex::new(start));
        let run: Arc<Check<u32, bool>> = Arc::new(move |c: &u32, _: &AtomicBool| {
            if *c == 0 {
                start.lock().unwrap().recv().unwrap();
                return Some(false);
            }
            started.lock().unwrap().send(()).unwrap();
            panic!("contact manifold overflow");
        });
        let caught =
            catch_unwind(AssertUnwindSafe(|| first_refusal(vec![0, 1], run, |r| *r))).unwrap_err();
        assert_eq!(panic_message(&*caught), "contact manifold overflow");
        t.join().unwrap();
        HELPERS.with(|h| *h.borrow_mut() = None);
    }
}
