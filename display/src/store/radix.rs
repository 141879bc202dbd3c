//! A stable least-significant-digit radix sort by integer key: batches are
//! sorted into the pixel index's memory order before insertion, so that
//! consecutive insertions walk the same, cached, branch of the index.

/// Widest digit: 2048 counters stay in the first-level cache.
const MAX_DIGIT: u32 = 11;

/// Sorts `v` by `key` (keys below `1 << bits`), stably, with `spare` as the
/// second buffer. Stability keeps the rays of one pixel in arrival order, so
/// ties and counters come out as without sorting.
pub fn radix_sort<T: Copy + Default>(v: &mut Vec<T>, spare: &mut Vec<T>, bits: u32, key: impl Fn(&T) -> u64) {
    if bits == 0 || v.len() < 2 {
        return;
    }
    let passes = bits.div_ceil(MAX_DIGIT);
    let digit = bits.div_ceil(passes);
    let mask = (1u64 << digit) - 1;
    let mut counts = vec![0usize; 1 << digit];
    spare.clear();
    spare.resize(v.len(), T::default());
    for pass in 0..passes {
        let shift = pass * digit;
        counts.fill(0);
        for p in v.iter() {
            counts[((key(p) >> shift) & mask) as usize] += 1;
        }
        if counts.contains(&v.len()) {
            continue;
        }
        let mut sum = 0;
        for c in counts.iter_mut() {
            let n = *c;
            *c = sum;
            sum += n;
        }
        for p in v.iter() {
            let d = ((key(p) >> shift) & mask) as usize;
            spare[counts[d]] = *p;
            counts[d] += 1;
        }
        std::mem::swap(v, spare);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn sorts_stably_like_the_standard_library(v in prop::collection::vec((0u64..1 << 23, 0u32..1000), 0..2000)) {
            let mut ours = v.clone();
            let mut spare = Vec::new();
            radix_sort(&mut ours, &mut spare, 23, |p| p.0);
            let mut theirs = v;
            theirs.sort_by_key(|p| p.0);
            prop_assert_eq!(ours, theirs);
        }
    }
}
