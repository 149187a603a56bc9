//! The one place that decides which vector instructions the accelerated
//! kernels use.
//!
//! Every kernel with an accelerated variant (the `Sim3` point transform, the
//! alignment moments, the backprojection filter, the octree ray tracer) has a
//! portable path beside it and dispatches on [`Isa::detect`]:
//!
//! ```ignore
//! match Isa::detect() {
//!     #[cfg(target_arch = "x86_64")]
//!     // SAFETY: `Isa::Avx2Fma` is only detected on a CPU with AVX2 and FMA.
//!     Isa::Avx2Fma => unsafe { kernel_avx2(args) },
//!     _ => kernel_portable(args),
//! }
//! ```
//!
//! Each module's tests run every [`Isa::available`] variant on the same input
//! and require the same bits. `SLAM2WORLD_SIMD=portable` in the environment
//! forces the portable paths (read once, at the first dispatch).

use std::sync::OnceLock;

/// An instruction set the kernels are compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// The target's baseline instructions; every kernel has this path.
    Portable,
    /// x86-64 AVX2 with FMA (the accelerated kernels need both).
    #[cfg(target_arch = "x86_64")]
    Avx2Fma,
    /// AArch64 NEON with fused multiply-add (part of the baseline there).
    #[cfg(target_arch = "aarch64")]
    Neon,
}

impl Isa {
    /// The widest instruction set this CPU runs (found once), or
    /// [`Isa::Portable`] when `SLAM2WORLD_SIMD=portable`.
    pub fn detect() -> Isa {
        static CHOSEN: OnceLock<Isa> = OnceLock::new();
        *CHOSEN.get_or_init(|| {
            let forced =
                std::env::var("SLAM2WORLD_SIMD").is_ok_and(|v| v.eq_ignore_ascii_case("portable"));
            if forced {
                Isa::Portable
            } else {
                Self::widest()
            }
        })
    }

    /// The widest instruction set of this CPU, ignoring the environment.
    fn widest() -> Isa {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return Isa::Avx2Fma;
        }
        #[cfg(target_arch = "aarch64")]
        return Isa::Neon;
        #[allow(unreachable_code)]
        Isa::Portable
    }

    /// Every instruction set this CPU runs, the portable one first (for the
    /// tests that compare the kernels).
    pub fn available() -> Vec<Isa> {
        let mut v = vec![Isa::Portable];
        let w = Self::widest();
        if w != Isa::Portable {
            v.push(w);
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn portable_first_and_the_detected_one_among_the_available() {
        let a = Isa::available();
        assert_eq!(a[0], Isa::Portable);
        assert!(a.contains(&Isa::detect()));
    }
}
