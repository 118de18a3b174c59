//! How a call enters rayon's pool: the planner and the CPU executor run there, their
//! parallel steps forked from a worker rather than each handed over from the caller.

use std::sync::atomic::{AtomicBool, Ordering};

/// Runs `work` on a thread of rayon's pool and returns what it returns (a panic in `work`
/// is resumed on the caller). Entered from outside the pool, the pool's other workers stay
/// awake for the call — each takes the jobs `work` forks as they appear instead of going
/// to sleep between the call's parallel steps; entered from a thread of the pool (a batch
/// already running in parallel), `work` runs there as it is.
///
/// Why: a plan and execution of ~1 500 triangles (the teapot at 1e-2 of its diagonal) is a
/// dozen parallel steps of 5–40 µs each, and waking a sleeping worker takes about as long,
/// so the second worker of a 2-thread pool took part in few of them: 187 → 173 µs a call
/// with the workers kept awake (medians of 12 interleaved runs on the 2-core development
/// machine). The cost is that the other workers poll for the call's duration, yielding
/// their core to the operating system between polls.
pub(crate) fn run_awake<R: Send>(work: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_some() {
        return work();
    }
    let done = AtomicBool::new(false);
    rayon::scope(|scope| {
        for _ in 1..rayon::current_num_threads() {
            scope.spawn(|_| {
                while !done.load(Ordering::Acquire) {
                    if rayon::yield_now() != Some(rayon::Yield::Executed) {
                        std::thread::yield_now();
                    }
                }
            });
        }
        // Set when `work` returns or unwinds: the scope waits for the pollers to stop.
        let _release = Release(&done);
        work()
    })
}

/// Tells the pollers of [`run_awake`] to stop, when dropped.
struct Release<'a>(&'a AtomicBool);

impl Drop for Release<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    // The test harness's threads are outside rayon's pools: each call here enters the
    // global pool as a caller's does.

    #[test]
    fn runs_the_work_on_a_worker_and_returns_its_result() {
        let (worker, sum) = run_awake(|| {
            let sum = (0..10_000u64).into_par_iter().sum::<u64>();
            (rayon::current_thread_index(), sum)
        });
        assert!(worker.is_some(), "the work runs on a thread of the pool");
        assert_eq!(sum, 10_000 * 9_999 / 2);
    }

    #[test]
    fn called_from_a_worker_the_work_stays_on_it() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("a test pool");
        let (caller, inner) = pool.install(|| {
            let caller = rayon::current_thread_index();
            (caller, run_awake(rayon::current_thread_index))
        });
        assert!(caller.is_some());
        assert_eq!(caller, inner);
    }

    #[test]
    fn a_panic_in_the_work_reaches_the_caller_and_releases_the_workers() {
        // Pollers left running would keep the scope, and the call, from ever returning:
        // the call runs on a thread of its own, and the test waits a minute at most.
        let (sender, answer) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let caught = std::panic::catch_unwind(|| {
                run_awake(|| {
                    (0..64).into_par_iter().for_each(|_| {});
                    panic!("planted");
                })
            });
            sender.send(caught.is_err()).unwrap();
        });
        let timeout = std::time::Duration::from_secs(60);
        assert_eq!(answer.recv_timeout(timeout), Ok(true));
        // The pool still runs calls: the failed call's pollers stopped with it.
        assert_eq!(run_awake(|| (0..100u32).into_par_iter().sum::<u32>()), 4950);
    }
}
