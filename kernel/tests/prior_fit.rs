//! The Markov prior fitted from the screwdriver's demonstration pattern reproduces the
//! paper's numbers: p(c_0) = [.8 turn, .1, .1], self-transitions .1, other transitions .45.

use dips_kernel::mode::{ModeId, Task};
use dips_kernel::prior::MarkovPrior;
use dips_kernel::rng::KernelRng;

const TURN: ModeId = ModeId(0);
const INDEX: ModeId = ModeId(1);
const THUMB_MIDDLE: ModeId = ModeId(2);

/// One 7-mode demo: turn, then the two regrasps in the given orders, turn, ...
fn demo(first_index: [bool; 2]) -> [ModeId; 7] {
    let pair = |index_first: bool| {
        if index_first {
            [INDEX, THUMB_MIDDLE]
        } else {
            [THUMB_MIDDLE, INDEX]
        }
    };
    let (a, b) = (pair(first_index[0]), pair(first_index[1]));
    [TURN, a[0], a[1], TURN, b[0], b[1], TURN]
}

fn check_paper_numbers(p: &MarkovPrior, tol: f32) {
    let close = |a: f32, b: f32| (a - b).abs() <= tol;
    assert!(close(p.probability(None, TURN), 0.8));
    assert!(close(p.probability(None, INDEX), 0.1));
    assert!(close(p.probability(None, THUMB_MIDDLE), 0.1));
    for from in [TURN, INDEX, THUMB_MIDDLE] {
        for to in [TURN, INDEX, THUMB_MIDDLE] {
            let want = if from == to { 0.1 } else { 0.45 };
            let got = p.probability(Some(from), to);
            assert!(close(got, want), "p({to:?}|{from:?}) = {got}, want {want}");
        }
    }
}

#[test]
fn balanced_screwdriver_data_gives_exactly_the_paper_prior() {
    let modes = Task::Screwdriver.mode_count();
    assert_eq!(Task::Screwdriver.mode_name(TURN), Some("turn"));
    // Every combination of regrasp orders once: the counts are exactly balanced.
    let demos = [
        demo([true, true]),
        demo([true, false]),
        demo([false, true]),
        demo([false, false]),
    ];
    let p = MarkovPrior::fit_with_floor(modes, demos, 0.1).unwrap();
    check_paper_numbers(&p, 1e-6);
    // Unfloored, the counts are a turn always first and 50/50 transitions.
    let raw = MarkovPrior::fit(modes, demos).unwrap();
    assert_eq!(raw.probability(None, TURN), 1.0);
    assert_eq!(raw.probability(Some(TURN), TURN), 0.0);
    assert_eq!(raw.probability(Some(INDEX), TURN), 0.5);
}

#[test]
fn random_order_demos_approach_the_paper_prior() {
    let mut rng = KernelRng::seed_from_u64(240);
    let demos: Vec<[ModeId; 7]> = (0..240)
        .map(|_| demo([rng.below(2) == 0, rng.below(2) == 0]))
        .collect();
    let p = MarkovPrior::fit_with_floor(3, &demos, 0.1).unwrap();
    check_paper_numbers(&p, 0.05);
    for from in [None, Some(TURN), Some(INDEX), Some(THUMB_MIDDLE)] {
        let sum: f32 = [TURN, INDEX, THUMB_MIDDLE]
            .iter()
            .map(|&m| p.probability(from, m))
            .sum();
        assert!((sum - 1.0).abs() < 1e-6);
    }
}

#[test]
fn rows_without_data_are_uniform_and_likelihoods_use_the_table() {
    // Card: only `index` then `both` seen; every other row has no data.
    let p = MarkovPrior::fit_with_floor(4, [[ModeId(0), ModeId(2)]], 0.1).unwrap();
    assert!((p.probability(Some(ModeId(3)), ModeId(1)) - 0.25).abs() < 1e-7);
    assert!((p.probability(None, ModeId(0)) - 0.7).abs() < 1e-6);
    assert!((p.probability(None, ModeId(1)) - 0.1).abs() < 1e-6);
    let ll = p.log_likelihood(&[ModeId(0), ModeId(2)]);
    assert!((ll - (libm::logf(0.7) + libm::logf(0.7))).abs() < 1e-5);
    let ll = p.log_likelihood_after(ModeId(3), &[ModeId(0)]);
    assert!((ll - libm::logf(0.25)).abs() < 1e-6);
}

mod properties {
    use dips_kernel::mode::{MAX_MODES, ModeId};
    use dips_kernel::prior::MarkovPrior;
    use proptest::prelude::*;

    proptest! {
        /// After the floor every row sums to one, no entry is below p_min, and entries that
        /// were above the floor keep their order.
        #[test]
        fn floored_rows_are_distributions_above_p_min(
            modes in 1usize..=MAX_MODES,
            raw in proptest::collection::vec(proptest::collection::vec(0u8..8, 0..12), 0..20),
            p_frac in 0.0f32..=1.0,
        ) {
            let seqs: Vec<Vec<ModeId>> = raw
                .iter()
                .map(|s| s.iter().map(|&m| ModeId(m % modes as u8)).collect())
                .collect();
            let p_min = p_frac / modes as f32;
            let fitted = MarkovPrior::fit(modes, &seqs).unwrap();
            let floored = fitted.with_floor(p_min).unwrap();
            for from in core::iter::once(None).chain((0..modes).map(|m| Some(ModeId(m as u8)))) {
                let row: Vec<f32> = (0..modes).map(|m| floored.probability(from, ModeId(m as u8))).collect();
                let orig: Vec<f32> = (0..modes).map(|m| fitted.probability(from, ModeId(m as u8))).collect();
                let sum: f32 = row.iter().sum();
                prop_assert!((sum - 1.0).abs() < 1e-5, "{row:?}");
                prop_assert!(row.iter().all(|&p| p >= p_min - 1e-6), "{row:?} < {p_min}");
                for i in 0..modes {
                    for j in 0..modes {
                        if orig[i] > orig[j] {
                            prop_assert!(row[i] >= row[j] - 1e-6, "{orig:?} -> {row:?}");
                        }
                    }
                }
            }
        }
    }
}
