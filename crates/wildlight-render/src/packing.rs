//! Rays with varying numbers of samples, packed in flat arrays.
//!
//! Every per-sample array of a batch is one flat slice; ray `r` owns the
//! samples `offsets[r] .. offsets[r + 1]` (`offsets.len()` = rays + 1,
//! `offsets[0]` = 0, non-decreasing). Parallel kernels split the rays into
//! fixed chunks of [`RAY_CHUNK`] rays, so every result (reductions included,
//! summed chunk by chunk in order) is bit-identical whatever the number of
//! threads.

use std::ops::Range;

/// Rays per parallel work item of every kernel of this crate.
pub const RAY_CHUNK: usize = 256;

/// The samples of ray `ray`.
#[inline]
pub fn samples_of(offsets: &[u32], ray: usize) -> Range<usize> {
    offsets[ray] as usize..offsets[ray + 1] as usize
}

/// Number of rays described by `offsets`.
#[inline]
pub fn ray_count(offsets: &[u32]) -> usize {
    offsets.len().saturating_sub(1)
}

/// Number of samples described by `offsets`.
#[inline]
pub fn sample_count(offsets: &[u32]) -> usize {
    offsets.last().map_or(0, |&n| n as usize)
}

/// A fixed chunk of rays and the samples they own.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RayChunk {
    /// Rays of the chunk.
    pub rays: Range<usize>,
    /// Samples of those rays.
    pub samples: Range<usize>,
}

/// The fixed chunks of [`RAY_CHUNK`] rays covering all rays of `offsets`.
pub fn ray_chunks(offsets: &[u32]) -> Vec<RayChunk> {
    let n = ray_count(offsets);
    (0..n)
        .step_by(RAY_CHUNK)
        .map(|r0| {
            let r1 = (r0 + RAY_CHUNK).min(n);
            RayChunk {
                rays: r0..r1,
                samples: offsets[r0] as usize..offsets[r1] as usize,
            }
        })
        .collect()
}

/// Splits `slice` into consecutive mutable pieces of the given contiguous
/// ranges (which must start at 0 and cover `slice` in order).
pub fn split_mut<X>(
    mut slice: &mut [X],
    ranges: impl Iterator<Item = Range<usize>>,
) -> Vec<&mut [X]> {
    let mut out = Vec::new();
    for r in ranges {
        let (head, tail) = slice.split_at_mut(r.end - r.start);
        out.push(head);
        slice = tail;
    }
    out
}

/// Writes the ray index of every sample into `out` (resized to the sample
/// count), for gathering per-ray data (view direction, light energy) per sample.
pub fn sample_rays(offsets: &[u32], out: &mut Vec<u32>) {
    out.clear();
    out.reserve(sample_count(offsets));
    for ray in 0..ray_count(offsets) {
        let n = (offsets[ray + 1] - offsets[ray]) as usize;
        out.extend(std::iter::repeat_n(ray as u32, n));
    }
}

/// Checks that `offsets` is a valid packing of `n_samples` samples:
/// starts at 0, never decreases and ends at `n_samples`.
pub fn validate_offsets(offsets: &[u32], n_samples: usize) -> bool {
    !offsets.is_empty()
        && offsets[0] == 0
        && offsets.windows(2).all(|w| w[0] <= w[1])
        && sample_count(offsets) == n_samples
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_cover_all_rays_and_samples_in_order() {
        let mut offsets = vec![0u32];
        for r in 0..(RAY_CHUNK * 2 + 7) {
            let last = *offsets.last().unwrap();
            offsets.push(last + (r % 5) as u32);
        }
        let chunks = ray_chunks(&offsets);
        assert_eq!(chunks.len(), 3);
        assert_eq!(chunks[0].rays, 0..RAY_CHUNK);
        assert_eq!(chunks[2].rays.end, RAY_CHUNK * 2 + 7);
        assert_eq!(chunks[2].samples.end, sample_count(&offsets));
        for w in chunks.windows(2) {
            assert_eq!(w[0].samples.end, w[1].samples.start);
        }
        let mut data = vec![0u8; sample_count(&offsets)];
        let pieces = split_mut(&mut data, chunks.iter().map(|c| c.samples.clone()));
        assert_eq!(pieces.len(), 3);
        assert_eq!(pieces[1].len(), chunks[1].samples.len());
        assert!(validate_offsets(&offsets, sample_count(&offsets)));
        let mut rays = Vec::new();
        sample_rays(&offsets, &mut rays);
        assert_eq!(rays.len(), sample_count(&offsets));
        for (k, &r) in rays.iter().enumerate() {
            assert!(samples_of(&offsets, r as usize).contains(&k));
        }
        assert!(!validate_offsets(&[0, 3, 2], 2));
        assert!(!validate_offsets(&[1, 3], 3));
    }
}
