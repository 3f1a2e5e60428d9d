//! Fork-join over disjoint chunks with `std::thread::scope` (the core uses no rayon).
//!
//! The thread count is `HEAPGRASP_NUM_THREADS` when set to a positive integer, else
//! [`std::thread::available_parallelism`]. Work below a size threshold stays on the
//! calling thread: spawning costs ~20 µs a thread, more than small kernels take.

use std::sync::OnceLock;

/// Number of worker threads the kernels use.
pub fn num_threads() -> usize {
    static N: OnceLock<usize> = OnceLock::new();
    *N.get_or_init(|| {
        std::env::var("HEAPGRASP_NUM_THREADS")
            .ok()
            .and_then(|s| s.trim().parse::<usize>().ok())
            .filter(|&n| n > 0)
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
    })
}

/// How many threads to use for `work` units of work, given that one thread should get
/// at least `min_work_per_thread` units, and at most `max_parts` parts exist.
pub fn threads_for(work: usize, min_work_per_thread: usize, max_parts: usize) -> usize {
    let by_work = work / min_work_per_thread.max(1);
    num_threads().min(by_work).min(max_parts).max(1)
}

/// Splits `0..n` into `parts` contiguous ranges of near-equal length.
pub fn split_range(n: usize, parts: usize) -> Vec<std::ops::Range<usize>> {
    let parts = parts.clamp(1, n.max(1));
    (0..parts)
        .map(|p| (p * n / parts)..((p + 1) * n / parts))
        .collect()
}

/// Runs `f(range, chunk)` for `parts` disjoint chunks of `data`, where each chunk holds
/// whole rows of `row_len` elements. Runs inline when `parts == 1`.
pub fn for_each_row_chunk<T: Send, F>(data: &mut [T], row_len: usize, parts: usize, f: F)
where
    F: Fn(std::ops::Range<usize>, &mut [T]) + Sync,
{
    let rows = data.len() / row_len.max(1);
    let ranges = split_range(rows, parts);
    if ranges.len() == 1 {
        f(0..rows, data);
        return;
    }
    std::thread::scope(|s| {
        let mut rest = data;
        for range in ranges {
            let (chunk, tail) = rest.split_at_mut(range.len() * row_len);
            rest = tail;
            let f = &f;
            s.spawn(move || f(range, chunk));
        }
    });
}

/// Like [`for_each_row_chunk`] for two buffers of equal length chunked in lockstep.
pub fn for_each_row_chunk_pair<T: Send, U: Send, F>(
    a: &mut [T],
    b: &mut [U],
    row_len: usize,
    parts: usize,
    f: F,
) where
    F: Fn(std::ops::Range<usize>, &mut [T], &mut [U]) + Sync,
{
    debug_assert_eq!(a.len(), b.len());
    let rows = a.len() / row_len.max(1);
    let ranges = split_range(rows, parts);
    if ranges.len() == 1 {
        f(0..rows, a, b);
        return;
    }
    std::thread::scope(|s| {
        let (mut rest_a, mut rest_b) = (a, b);
        for range in ranges {
            let (chunk_a, tail_a) = rest_a.split_at_mut(range.len() * row_len);
            let (chunk_b, tail_b) = rest_b.split_at_mut(range.len() * row_len);
            rest_a = tail_a;
            rest_b = tail_b;
            let f = &f;
            s.spawn(move || f(range, chunk_a, chunk_b));
        }
    });
}

/// Maps `f` over `parts` contiguous sub-ranges of `0..n` in parallel and returns the
/// results in order.
pub fn map_ranges<R: Send, F>(n: usize, parts: usize, f: F) -> Vec<R>
where
    F: Fn(std::ops::Range<usize>) -> R + Sync,
{
    let ranges = split_range(n, parts);
    if ranges.len() == 1 {
        return ranges.into_iter().map(&f).collect();
    }
    std::thread::scope(|s| {
        let handles: Vec<_> = ranges
            .into_iter()
            .map(|r| {
                let f = &f;
                s.spawn(move || f(r))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| match h.join() {
                Ok(v) => v,
                Err(payload) => std::panic::resume_unwind(payload),
            })
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_range_covers_everything_once() {
        for n in [0, 1, 5, 40, 41] {
            for parts in 1..6 {
                let r = split_range(n, parts);
                let total: usize = r.iter().map(|x| x.len()).sum();
                assert_eq!(total, n);
                assert!(r.windows(2).all(|w| w[0].end == w[1].start));
            }
        }
    }

    #[test]
    fn row_chunks_see_their_rows() {
        let mut data = vec![0usize; 30];
        for_each_row_chunk(&mut data, 3, 4, |rows, chunk| {
            for (i, row) in rows.zip(chunk.chunks_mut(3)) {
                row.iter_mut().for_each(|x| *x = i);
            }
        });
        assert!(data.iter().enumerate().all(|(k, &x)| x == k / 3));
    }
}
