//! The one chunk planner of the GPU executor: every kernel family binds its buffers in
//! ranges no larger than the device allows, so its items are split into chunks of
//! consecutive items whose ranges all fit, and each chunk is dispatched with its own
//! bindings.

use std::ops::Range;

/// Splits items `0..count` into runs of consecutive items, each as long as every one of its
/// N bindings fits `budget` bytes: `span_bytes(first, last)` gives what each binding needs
/// for items `first..=last`. A chunk always takes its first item (callers refuse an item
/// that alone exceeds the budget before planning).
pub(super) fn chunk_ranges<const N: usize>(
    count: usize,
    budget: u64,
    span_bytes: impl Fn(usize, usize) -> [u64; N],
) -> Vec<Range<usize>> {
    let mut ranges = Vec::new();
    let mut start = 0;
    while start < count {
        let mut end = start + 1;
        while end < count && span_bytes(start, end).iter().all(|&b| b <= budget) {
            end += 1;
        }
        ranges.push(start..end);
        start = end;
    }
    ranges
}

/// [`chunk_ranges`] for items whose bytes add up: item k needs `needs[k]` in each binding.
pub(super) fn additive_chunk_ranges<const N: usize>(
    needs: &[[u64; N]],
    budget: u64,
) -> Vec<Range<usize>> {
    let mut prefix = vec![[0u64; N]];
    for need in needs {
        let last = prefix[prefix.len() - 1];
        prefix.push(std::array::from_fn(|b| last[b] + need[b]));
    }
    chunk_ranges::<N>(needs.len(), budget, |first, last| {
        std::array::from_fn(|b| prefix[last + 1][b] - prefix[first][b])
    })
}

/// The first of `needs` (what, bytes) over `budget`, if any: an item no chunk can hold.
pub(super) fn over_budget<const N: usize>(
    needs: &[(&'static str, u64); N],
    budget: u64,
) -> Option<(&'static str, u64)> {
    needs.iter().copied().find(|&(_, bytes)| bytes > budget)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Chunks cover every item once, in order; each fits the budget in every binding (or
    /// holds one item); adding the next item would not have fitted.
    #[test]
    fn chunks_are_greedy_and_cover_every_item() {
        let needs: Vec<[u64; 2]> = (0..40).map(|k| [10 + k % 7, 3 + (k * 5) % 11]).collect();
        let budget = 60;
        let ranges = additive_chunk_ranges(&needs, budget);
        let total = |r: &Range<usize>, b: usize| needs[r.clone()].iter().map(|n| n[b]).sum::<u64>();
        let mut next = 0;
        for range in &ranges {
            assert_eq!(range.start, next);
            assert!((0..2).all(|b| total(range, b) <= budget) || range.len() == 1);
            if range.end < needs.len() {
                let longer = range.start..range.end + 1;
                assert!((0..2).any(|b| total(&longer, b) > budget));
            }
            next = range.end;
        }
        assert_eq!(next, needs.len());
        assert_eq!(
            additive_chunk_ranges(&[[100u64]], 10),
            vec![std::ops::Range { start: 0, end: 1 }]
        );
        assert!(additive_chunk_ranges::<1>(&[], 10).is_empty());
    }
}
