//! Wider vectors where the CPU has them, with the same results bit for bit.
//!
//! The hot op kernels are written once as plain loops that the compiler vectorizes. On x86
//! the baseline is SSE2 (4 lanes); `wide!` compiles a second copy of a kernel with AVX2
//! enabled (8 lanes, 16 vector registers) and picks it at run time when the CPU reports AVX2
//! (`cpufeatures`, no_std: CPUID and XGETBV, read once). FMA is not enabled, and Rust never
//! fuses a multiply and an add on its own, so every sum is rounded in the same order in both
//! copies: a plan is the same bit for bit on a machine with AVX2, without it, and on the
//! controller (`docs/kernel.md`). Other architectures get the plain copy only.

use core::sync::atomic::{AtomicBool, Ordering};

#[cfg(any(target_arch = "x86_64", target_arch = "x86"))]
cpufeatures::new!(cpuid_avx2, "avx2");

/// Whether the wide copies may run (on by default; see [`allow_wide`]).
static WIDE_ALLOWED: AtomicBool = AtomicBool::new(true);

/// Let the AVX2 copies run where the CPU has AVX2 (`true`, the default) or always run the
/// baseline copies (`false`), for the whole process. Results are the same either way; this
/// exists to measure the difference and to test that it is none.
pub fn allow_wide(allow: bool) {
    WIDE_ALLOWED.store(allow, Ordering::Relaxed);
}

/// Whether the AVX2 copies run: allowed ([`allow_wide`]) and the CPU has AVX2 (never off
/// x86).
#[inline]
pub fn wide_in_use() -> bool {
    #[cfg(any(target_arch = "x86_64", target_arch = "x86"))]
    {
        WIDE_ALLOWED.load(Ordering::Relaxed) && cpuid_avx2::get()
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "x86")))]
    {
        false
    }
}

/// `√x`, correctly rounded as IEEE 754 requires, so the same bits as `libm::sqrtf` on every
/// target. On x86_64 it is the SSE intrinsic, which LLVM schedules like any other instruction
/// (and encodes as `vsqrtss` inside the AVX2 copies); `libm::sqrtf` there is an opaque inline
/// `sqrtss` block, and in group normalization's AVX2 copy it cost 3× the whole rest of the
/// op (`group_norm_throughput`: 1.95 → 0.6 ns per element without it).
#[inline(always)]
pub fn sqrt(x: f32) -> f32 {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_mm_cvtss_f32, _mm_set_ss, _mm_sqrt_ss};
        // SAFETY: SSE is part of the x86_64 baseline, so the CPU has these intrinsics' target
        // feature; they touch no memory.
        #[allow(unsafe_code)]
        unsafe {
            _mm_cvtss_f32(_mm_sqrt_ss(_mm_set_ss(x)))
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        libm::sqrtf(x)
    }
}

/// `wide! { /// docs
/// pub fn name(args…) -> R = body; }` defines `name`, which calls `body` (an
/// `#[inline(always)]` function with the same arguments) through a copy compiled with AVX2
/// when [`wide_in_use`] holds, and directly otherwise. `= narrow | wide;` names a different
/// body for each copy (the same computation blocked for the register count).
macro_rules! wide {
    ($(#[$m:meta])* pub fn $name:ident($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty = $body:path;) => {
        $crate::nn::ops::cpu::wide! {
            $(#[$m])* pub fn $name($($arg: $ty),*) -> $ret = $body | $body;
        }
    };
    ($(#[$m:meta])* pub fn $name:ident($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty
        = $narrow:path | $wide:path;) => {
        $(#[$m])*
        pub fn $name($($arg: $ty),*) -> $ret {
            #[cfg(any(target_arch = "x86_64", target_arch = "x86"))]
            if $crate::nn::ops::cpu::wide_in_use() {
                #[target_feature(enable = "avx2")]
                #[allow(clippy::too_many_arguments)]
                fn avx2($($arg: $ty),*) -> $ret {
                    $wide($($arg),*)
                }
                // SAFETY: the CPU reports AVX2 (and the OS saves its registers).
                #[allow(unsafe_code)]
                return unsafe { avx2($($arg),*) };
            }
            $narrow($($arg),*)
        }
    };
}
pub(crate) use wide;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::format::{BinaryFn, ConvGeom};
    use crate::nn::ops::testutil::rand_vec;
    use crate::nn::ops::{conv, elementwise, gemm, norm};
    use std::vec;
    use std::vec::Vec;

    /// Run `f` with the wide copies allowed and then forbidden; both results.
    fn both<T>(mut f: impl FnMut() -> T) -> (T, T) {
        allow_wide(true);
        let wide = f();
        allow_wide(false);
        let narrow = f();
        allow_wide(true);
        (wide, narrow)
    }

    fn bits(v: &[f32]) -> Vec<u32> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    #[test]
    fn wide_and_narrow_copies_agree_bit_for_bit() {
        // Shapes of the shipped models' layers, odd channel counts and a tail block included.
        for (i, &(cin, cout, lin, s)) in [
            (64, 64, 3, 1),
            (48, 29, 12, 1),
            (29, 16, 9, 2),
            (96, 40, 6, 1),
        ]
        .iter()
        .enumerate()
        {
            let seed = 10 * i as u64;
            let coutp = conv::padded_channels(cout);
            let lout = (lin + 2 - 3) / s + 1;
            let g = ConvGeom {
                cin: cin as u32,
                cout: cout as u32,
                cout_padded: coutp as u32,
                lin: lin as u32,
                lout: lout as u32,
                k: 3,
                stride: s as u32,
                dilation: 1,
                pad_begin: 1,
            };
            let x = rand_vec(cin * lin, seed);
            let w = rand_vec(cin * 3 * coutp, seed + 1);
            let b = rand_vec(coutp, seed + 2);
            let (wide, narrow) = both(|| {
                let mut y = vec![0.0; cout * lout];
                let mut temp = vec![0.0; conv::conv1d_temp_len(&g).unwrap()];
                conv::conv1d(&g, &x, &mut y, &w, &b, &mut temp).unwrap();
                bits(&y)
            });
            assert_eq!(wide, narrow, "conv1d {cin}→{cout}");
            let gt = ConvGeom {
                lin: lout as u32,
                lout: lin as u32,
                ..g
            };
            let xt = rand_vec(cin * lout, seed + 3);
            let (wide, narrow) = both(|| {
                let mut y = vec![0.0; cout * lin];
                let mut temp = vec![0.0; conv::conv_transpose1d_temp_len(&gt).unwrap()];
                conv::conv_transpose1d(&gt, &xt, &mut y, &w, &b, &mut temp).unwrap();
                bits(&y)
            });
            assert_eq!(wide, narrow, "conv_transpose1d {cin}→{cout}");
            let gamma = rand_vec(cout, seed + 4);
            let beta = rand_vec(cout, seed + 5);
            let xn: Vec<f32> = rand_vec(cout * lin, seed + 6)
                .iter()
                .map(|v| 6.0 * v)
                .collect();
            let groups = if cout % 8 == 0 { 8 } else { 1 };
            let (wide, narrow) = both(|| {
                let mut y = vec![0.0; cout * lin];
                norm::group_norm(
                    &xn,
                    &mut y,
                    cout / groups * lin,
                    lin,
                    1e-5,
                    &gamma,
                    &beta,
                    true,
                )
                .unwrap();
                bits(&y)
            });
            assert_eq!(wide, narrow, "group_norm {cout}×{lin}");
            let (wide, narrow) = both(|| {
                let mut y = vec![0.0; lin * cout];
                gemm::gemm(&xn, &w[..cout * cout], &b[..cout], &mut y, cout, cout).unwrap();
                bits(&y)
            });
            assert_eq!(wide, narrow, "gemm {cout}");
            let u = |v: [usize; 4]| v.map(|d| d as u32);
            let (wide, narrow) = both(|| {
                let mut y = vec![0.0; cout * lin];
                let (dims, sa, sb) = (u([1, 1, cout, lin]), u([0, 0, lin, 1]), u([0, 0, 1, 0]));
                elementwise::binary(BinaryFn::Mul, &xn, &b, &mut y, &dims, &sa, &sb).unwrap();
                bits(&y)
            });
            assert_eq!(wide, narrow, "binary {cout}×{lin}");
        }
    }
}
