//! The instruction-set paths of RPF's inner loops, chosen once at run time: the same integer
//! counts and the same floating-point operations in the same order on every path, so the output
//! does not depend on the CPU (the unit tests of `mi` compare the paths bit for bit).
//!
//! The build targets baseline x86-64 (SSE2), which has no `popcnt`; the machines RPF runs on
//! mostly have it, and AVX-512 with `vpopcntq` and byte compares into bit masks. A loop is
//! written once, as an `#[inline(always)]` function, and compiled again inside
//! `#[target_feature]` wrappers, so the compiler may use those instructions there; the callers
//! pick the wrapper with [`Level::detect`].

/// An instruction-set level of the host CPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// Whatever the build targets (no run-time features).
    Generic,
    /// x86-64 with `popcnt`.
    Popcnt,
    /// x86-64 with AVX-512 F, BW, DQ, VL and VPOPCNTDQ (and AVX2, FMA, which every such CPU
    /// has).
    Avx512,
}

impl Level {
    /// The best level this CPU supports (`NOISEFREE_RPF_SIMD=generic|popcnt|avx512` caps it,
    /// to compare the paths on whole images).
    pub fn detect() -> Level {
        static LEVEL: std::sync::OnceLock<Level> = std::sync::OnceLock::new();
        *LEVEL.get_or_init(|| {
            let cap = match std::env::var("NOISEFREE_RPF_SIMD").as_deref() {
                Ok("generic") => Level::Generic,
                Ok("popcnt") => Level::Popcnt,
                _ => Level::Avx512,
            };
            Level::best().min_with(cap)
        })
    }

    /// Every level this CPU can run, lowest first.
    pub fn available() -> Vec<Level> {
        let best = Level::best();
        [Level::Generic, Level::Popcnt, Level::Avx512]
            .into_iter()
            .filter(|l| l.rank() <= best.rank())
            .collect()
    }

    fn rank(self) -> u8 {
        match self {
            Level::Generic => 0,
            Level::Popcnt => 1,
            Level::Avx512 => 2,
        }
    }

    fn min_with(self, cap: Level) -> Level {
        if cap.rank() < self.rank() { cap } else { self }
    }

    #[cfg(target_arch = "x86_64")]
    fn best() -> Level {
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512bw")
            && std::arch::is_x86_feature_detected!("avx512dq")
            && std::arch::is_x86_feature_detected!("avx512vl")
            && std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("avx512vpopcntdq")
            && std::arch::is_x86_feature_detected!("popcnt")
        {
            Level::Avx512
        } else if std::arch::is_x86_feature_detected!("popcnt") {
            Level::Popcnt
        } else {
            Level::Generic
        }
    }

    #[cfg(not(target_arch = "x86_64"))]
    fn best() -> Level {
        Level::Generic
    }
}

/// Asks the CPU to bring the cache line holding `p` closer (a hint: it cannot fault, and does
/// nothing where the architecture has no such instruction here).
#[inline(always)]
pub fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of x86-64; a prefetch reads nothing and cannot fault.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p as *const i8)
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
