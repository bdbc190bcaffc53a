//! Intermediate targets: the soft cap on a step's target/mass ratios (module docs of
//! `newton`, "Intermediate targets"; `docs/decisions/0004-intermediate-targets.md`).

/// Default of [`NewtonParams::target_ratio_cap`](crate::newton::NewtonParams::target_ratio_cap). Measured (`docs/decisions/0004-intermediate-targets.md`): on 8
/// faces (28 distance pairs) 16, 24, 32, 64, 128 and 256 with a hard cap all cut the finest
/// level's evaluations by about a fifth, 4 and 1000 less; the soft cap at 32 cut the steps over
/// all levels 697 → 603 and the evaluations of the finest level 450 → 315.
pub const TARGET_RATIO_CAP: f64 = 32.0;

/// A step's target is left at ν_i when the soft cap would change it by less than this fraction.
const TARGET_CAP_SLACK: f64 = 1e-3;

/// A step aimed at intermediate targets and accepted below this τ switches them off for the
/// rest of the solve.
pub(super) const TARGET_CAP_MIN_TAU: f64 = 0.01;

/// The intermediate targets ν' of one Newton step (module docs, "Intermediate targets"):
/// ν'_i = m_i exp(K tanh(ln(ν_i/m_i)/K)) with K = ln `cap`, or ν_i where that differs from ν_i by
/// less than `TARGET_CAP_SLACK` (relative), all rescaled to Σ ν, with the number of cells whose
/// target was capped. `None` when no target changes.
/// Cells with zero mass (not expected: the line search keeps masses ≥ ε₀ > 0) keep ν_i.
pub(crate) fn intermediate_targets(masses: &[f64], targets: &[f64], cap: f64) -> Option<(Vec<f64>, usize)> {
    let k = cap.ln();
    let mut changed = 0;
    let mut out: Vec<f64> = masses
        .iter()
        .zip(targets)
        .map(|(&m, &nu)| {
            let r = nu / m;
            if !(m > 0.0 && r.is_finite()) {
                return nu;
            }
            let capped = (k * (r.ln() / k).tanh()).exp();
            if (capped / r - 1.0).abs() < TARGET_CAP_SLACK {
                nu
            } else {
                changed += 1;
                m * capped
            }
        })
        .collect();
    if changed == 0 {
        return None;
    }
    let scale = targets.iter().sum::<f64>() / out.iter().sum::<f64>();
    out.iter_mut().for_each(|t| *t *= scale);
    Some((out, changed))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The soft cap (κ = 32, K = ln 32): a cell with 1e-3 of its target aims at
    /// exp(K tanh(ln 1000 / K)) ≈ 28.2 times its mass, one with 10 times its target at
    /// exp(K tanh(ln 0.1 / K)) ≈ 0.133 of it; cells at 0.9 and 1.2 of their targets (a change
    /// below 0.1 %) keep them; the targets are rescaled to their old sum. All within the band:
    /// no intermediate targets.
    #[test]
    fn intermediate_targets_soft_cap_far_cells_and_keep_near_ones() {
        let masses = [1e-3, 1.0, 10.0, 1.2, 0.9];
        let targets = [1.0; 5];
        let (step, capped) = intermediate_targets(&masses, &targets, 32.0).unwrap();
        assert_eq!(capped, 2);
        let k = 32f64.ln();
        let raw = [
            1e-3 * (k * (1000f64.ln() / k).tanh()).exp(),
            1.0,
            10.0 * (k * (0.1f64.ln() / k).tanh()).exp(),
            1.0,
            1.0,
        ];
        assert!(
            (raw[0] / 1e-3 - 28.2).abs() < 0.05 && (raw[2] / 10.0 - 0.1333).abs() < 1e-3,
            "{raw:?}"
        );
        let scale = 5.0 / raw.iter().sum::<f64>();
        for i in 0..5 {
            assert!(
                (step[i] - scale * raw[i]).abs() <= 1e-15 * raw[i],
                "{i}: {} vs {}",
                step[i],
                scale * raw[i]
            );
            // between the mass and the target (before the common rescaling)
            let (lo, hi) = (masses[i].min(targets[i]), masses[i].max(targets[i]));
            assert!(lo <= raw[i] && raw[i] <= hi);
        }
        assert!((step.iter().sum::<f64>() - 5.0).abs() < 1e-14);
        assert!(intermediate_targets(&[0.8, 1.3, 1.0], &[1.0; 3], 32.0).is_none());
    }
}
