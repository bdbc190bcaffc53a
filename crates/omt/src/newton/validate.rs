//! Validation of an OT problem's input before the solve: targets, masses, parameters and
//! the source measure, each failure a typed error naming what is wrong.

use super::*;

/// Checks the input of [`solve_ot`] (module docs): an error for the first problem found.
pub(super) fn validate(
    measure: &SourceMeasure,
    points: &[[f64; 2]],
    masses: &[f64],
    params: &NewtonParams,
) -> Result<(), OmtError> {
    if points.is_empty() {
        return Err(OmtError::InvalidInput("no target point".into()));
    }
    if points.len() != masses.len() {
        return Err(OmtError::InvalidInput(format!(
            "{} target points but {} masses",
            points.len(),
            masses.len()
        )));
    }
    if points.len() > u32::MAX as usize - 1 {
        return Err(OmtError::InvalidInput(format!(
            "{} target points exceed the u32 index range",
            points.len()
        )));
    }
    if let Some(i) = points.iter().position(|p| !(p[0].is_finite() && p[1].is_finite())) {
        return Err(OmtError::InvalidInput(format!("target point {i} is not finite")));
    }
    // The power diagram's documented range (|x| ≤ 1e30: lifted heights |y|² stay finite).
    if let Some(i) = points.iter().position(|p| p[0].abs() > 1e30 || p[1].abs() > 1e30) {
        return Err(OmtError::InvalidInput(format!(
            "target point {i} = ({:e}, {:e}) is beyond the supported range |x| <= 1e30; rescale the points",
            points[i][0], points[i][1]
        )));
    }
    // Cells are clipped relative to their sites (`restricted`): a target far beyond the source
    // would see its triangles round to points.
    let (lo, hi) = crate::polygon::bounding_box(&measure.vertices);
    let diameter = (hi[0] - lo[0]).hypot(hi[1] - lo[1]);
    let reach = crate::restricted::MAX_SITE_DISTANCE * diameter;
    let outside = |p: &[f64; 2]| {
        let dx = (lo[0] - p[0]).max(p[0] - hi[0]).max(0.0);
        let dy = (lo[1] - p[1]).max(p[1] - hi[1]).max(0.0);
        dx.hypot(dy)
    };
    if let Some(i) = points.iter().position(|p| outside(p) > reach) {
        return Err(OmtError::InvalidInput(format!(
            "target point {i} = ({:e}, {:e}) lies {:e} from the source, beyond {:e} source diameters ({:e}); move the points nearer or rescale the source",
            points[i][0],
            points[i][1],
            outside(&points[i]),
            crate::restricted::MAX_SITE_DISTANCE,
            diameter
        )));
    }
    if let Some(i) = masses.iter().position(|m| !(m.is_finite() && *m > 0.0)) {
        return Err(OmtError::InvalidInput(format!(
            "target mass {i} is {} (must be finite and > 0)",
            masses[i]
        )));
    }
    let total = measure.total_mass();
    if !(total.is_finite() && total > 0.0) {
        return Err(OmtError::InvalidInput(format!(
            "the source measure's total mass is {total} (its triangles' areas times densities must sum to a finite positive number; rescale the density mesh or the densities)"
        )));
    }
    // The targets are the masses rescaled to the source's mass (module docs): that rescaling
    // must stay within f64 (masses of 1e308 overflow their sum, subnormal ones the scale).
    let sum: f64 = masses.iter().sum();
    let scale = total / sum;
    let representable = |m: f64| {
        let t = m * scale;
        t.is_finite() && t > 0.0
    };
    if !(sum.is_finite() && scale.is_finite() && scale > 0.0) {
        return Err(OmtError::InvalidInput(format!(
            "the target masses sum to {sum:e}, which cannot be rescaled to the source's mass {total:e} in double precision; rescale the masses (e.g. divide them by the largest)"
        )));
    }
    // the sum is fine, but one mass is too small beside the others for its rescaled value
    if let Some(i) = masses.iter().position(|&m| !representable(m)) {
        return Err(OmtError::InvalidInput(format!(
            "target mass {i} is {:e}, too small beside the others (they sum to {sum:e}): rescaled to the source's mass {total:e} it underflows double precision; drop that point or merge it with a neighbour",
            masses[i]
        )));
    }
    if !(params.coarse_tolerance > 0.0 && params.coarse_tolerance < 1.0) {
        return Err(OmtError::InvalidInput(format!(
            "coarse tolerance {} must be in (0, 1): it bounds the coarse levels' relative mass errors",
            params.coarse_tolerance
        )));
    }
    if !(params.tolerance > 0.0 && params.tolerance < 1.0) {
        return Err(OmtError::InvalidInput(format!(
            "tolerance {} must be in (0, 1): it bounds every cell's relative mass error",
            params.tolerance
        )));
    }
    if let Some(cap) = params.target_ratio_cap {
        if !(cap > 1.0 && cap.is_finite()) {
            return Err(OmtError::InvalidInput(format!(
                "target ratio cap {cap} must be finite and > 1 (None turns the intermediate targets off)"
            )));
        }
    }
    if let Some(h) = &params.initial_heights {
        if h.len() != points.len() {
            return Err(OmtError::InvalidInput(format!(
                "{} initial heights for {} points",
                h.len(),
                points.len()
            )));
        }
        if let Some(i) = h.iter().position(|v| !v.is_finite()) {
            return Err(OmtError::InvalidInput(format!("initial height {i} is not finite")));
        }
        if let Some(lo) = &params.initial_heights_lo {
            if lo.len() != h.len() {
                return Err(OmtError::InvalidInput(format!(
                    "{} low parts for {} initial heights",
                    lo.len(),
                    h.len()
                )));
            }
            if let Some(i) = lo.iter().position(|v| !v.is_finite()) {
                return Err(OmtError::InvalidInput(format!(
                    "low part {i} of the initial heights is not finite"
                )));
            }
        }
    }
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_unstable_by(|&a, &b| {
        points[a][0]
            .total_cmp(&points[b][0])
            .then(points[a][1].total_cmp(&points[b][1]))
    });
    for w in order.windows(2) {
        if points[w[0]] == points[w[1]] {
            return Err(OmtError::DuplicatePoints {
                i: w[0].min(w[1]),
                j: w[0].max(w[1]),
            });
        }
    }
    Ok(())
}
