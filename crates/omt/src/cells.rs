//! Integrals over power cells restricted to the source domain: the quantities the Newton solver
//! and the transport cost need. Shared by the fast path (`restricted`) and the brute-force
//! oracle (`reference`).

/// Integrals over the restricted power cells W_i ∩ Ω of a source measure μ, for sites y_i.
///
/// All are exact for a piecewise-constant density on triangles (up to floating point).
#[derive(Clone, Debug, Default)]
pub struct CellIntegrals {
    /// μ(W_i ∩ Ω), #N. Zero for empty (hidden or outside) cells.
    pub masses: Vec<f64>,
    /// ∫_{W_i ∩ Ω} x dμ(x), #N (divide by the mass for the centroid).
    pub first_moments: Vec<[f64; 2]>,
    /// ∫_{W_i ∩ Ω} |x − y_i|² dμ(x), #N: the transport cost of cell i.
    pub second_moments: Vec<f64>,
    /// For each pair of neighbouring cells i < j whose shared edge meets Ω:
    /// (i, j, ∫_{e_ij ∩ Ω} μ ds), the μ-weighted length of the common edge.
    pub edge_masses: Vec<(u32, u32, f64)>,
}

impl CellIntegrals {
    /// μ-centroids of the cells, #N; `None` for an empty cell.
    pub fn centroids(&self) -> Vec<Option<[f64; 2]>> {
        self.masses
            .iter()
            .zip(&self.first_moments)
            .map(|(&m, c)| if m > 0.0 { Some([c[0] / m, c[1] / m]) } else { None })
            .collect()
    }

    /// Whether the moments were computed (the flux form of a Newton evaluation leaves them
    /// empty: [`crate::restricted::RestrictedIntegrator::integrate_masses`]).
    pub fn has_moments(&self) -> bool {
        self.first_moments.len() == self.masses.len() && self.second_moments.len() == self.masses.len()
    }

    /// Total transport cost Σ_i ∫_{W_i} |x − y_i|² dμ.
    pub fn transport_cost(&self) -> f64 {
        self.second_moments.iter().sum()
    }
}
