//! Large zeroed buffers backed by transparent huge pages where the kernel offers them.
//!
//! A 512^3 sweep touches about 2 GB of fresh buffers; with 4 KiB pages that is half a million
//! page faults (a tenth of the sweep's time, measured in docs/benchmarks.md). Linux kernels in
//! `madvise` mode (`/sys/kernel/mm/transparent_hugepage/enabled`) back a range with 2 MiB pages
//! when asked before its first touch; numpy asks for every large array, and so do we, for the
//! buffers of the sweeps and of tube meshes (a 255 MB mesh then costs about a hundred page
//! faults instead of sixty thousand). Elsewhere this is a plain zeroed `Vec`.

/// Buffers below this size are left alone.
const HUGE: usize = 4 << 20;

/// `vec![zero; n]` (zeroed pages from the allocator, untouched), with transparent huge pages
/// requested for it on Linux.
/// (`vec!` allocates zeroed pages without touching them for the zero of the primitive types.)
pub fn zeroed<T: Copy>(n: usize, zero: T) -> Vec<T> {
    let v = vec![zero; n];
    advise_huge(&v);
    v
}

/// Asks the kernel to back the whole 2 MiB pages inside `v` with huge pages (a hint: errors
/// are ignored, and nothing is done off Linux or for small buffers). `v` may be the spare
/// capacity of a `Vec` (`MaybeUninit` elements) about to be written.
pub fn advise_huge<T>(v: &[T]) {
    let bytes = std::mem::size_of_val(v);
    if bytes < HUGE {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        const PAGE: usize = 2 << 20;
        let start = v.as_ptr() as usize;
        let lo = start.div_ceil(PAGE) * PAGE;
        let hi = (start + bytes) / PAGE * PAGE;
        if hi > lo {
            // SAFETY: the range lies inside the slice's allocation; MADV_HUGEPAGE changes how
            // pages are backed, never their contents.
            unsafe {
                libc::madvise(lo as *mut libc::c_void, hi - lo, libc::MADV_HUGEPAGE);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn zeroed_buffers_are_zero_and_sized() {
        let v = super::zeroed(3 << 20, 0u32);
        assert_eq!(v.len(), 3 << 20);
        assert!(v.iter().all(|&x| x == 0));
        let small = super::zeroed(7, 0.0f32);
        assert_eq!(small, vec![0.0; 7]);
    }
}
