//! What the benchmark commands share: timing one piece of work (medians of repeats are
//! `crate::maths::median`), in one place, so that every figure in BENCHMARKS.md is measured the same way (wall time from just
//! before the work to just after it, nothing else inside).

use std::time::Instant;

/// Runs `work` once: its result and its wall time, seconds.
pub fn timed<T>(work: impl FnOnce() -> T) -> (T, f64) {
    let start = Instant::now();
    let out = work();
    (out, start.elapsed().as_secs_f64())
}

/// Runs `work` once: its result and its wall time, milliseconds.
pub fn timed_ms<T>(work: impl FnOnce() -> T) -> (T, f64) {
    let (out, s) = timed(work);
    (out, s * 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_timing_covers_the_work_and_keeps_its_result() {
        let (v, s) = timed(|| {
            std::thread::sleep(std::time::Duration::from_millis(20));
            7
        });
        assert_eq!(v, 7);
        assert!(s >= 0.02, "{s}");
        let ((), ms) = timed_ms(|| std::thread::sleep(std::time::Duration::from_millis(5)));
        assert!(ms >= 5.0, "{ms}");
    }
}
