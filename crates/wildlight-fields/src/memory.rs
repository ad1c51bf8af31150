//! Large buffers: hash tables and their gradients are accessed at random, so
//! they are backed by transparent huge pages where the OS allows it (fewer TLB
//! misses), and touched through software prefetches.

use wildlight_real::Real;

const HUGE_PAGE: usize = 2 << 20;

/// A zero-filled vector of `n` values whose 2 MiB-aligned interior is advised
/// to use transparent huge pages (Linux; a plain vector elsewhere).
pub fn huge_vec<T: Real>(n: usize) -> Vec<T> {
    let mut v: Vec<T> = Vec::with_capacity(n);
    let bytes = n * std::mem::size_of::<T>();
    #[cfg(target_os = "linux")]
    if bytes >= 2 * HUGE_PAGE {
        let start = v.as_ptr() as usize;
        let aligned = start.next_multiple_of(HUGE_PAGE);
        let end = (start + bytes) / HUGE_PAGE * HUGE_PAGE;
        if end > aligned {
            // SAFETY: the range lies inside the (untouched) allocation of `v`;
            // MADV_HUGEPAGE only changes how the kernel backs it.
            unsafe {
                libc::madvise(
                    aligned as *mut libc::c_void,
                    end - aligned,
                    libc::MADV_HUGEPAGE,
                );
            }
        }
    }
    let _ = bytes;
    v.resize(n, T::ZERO);
    v
}

/// Hints the CPU to fetch the cache line holding `p` into L1.
#[inline(always)]
pub fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: prefetch never faults, whatever the address.
    unsafe {
        core::arch::x86_64::_mm_prefetch(p as *const i8, core::arch::x86_64::_MM_HINT_T0);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
