//! A source measure with what the solver builds from it once and reuses across solves.
//!
//! [`SourceMeasure`] is plain data. A solve derives two things from it that cost more than a
//! Newton step on a large measure and do not depend on the targets: the averaged copies of the
//! coarse levels of the coarse-to-fine start ([`crate::averaging`]) and the Raviart–Thomas field of
//! the flux form ([`crate::restricted`], opt-in). A [`PreparedMeasure`] owns the measure and
//! builds each of them on first use; pairwise runs, which solve from one source measure many
//! times, pass the same prepared measure (or clones of it, which share what was built) to
//! [`crate::solve_ot_prepared`]. The measure inside cannot change, so nothing built from it can go
//! stale. Caching changes speed only, never a bit of a result.

use std::sync::{Arc, Mutex};

use crate::measure::SourceMeasure;
use crate::restricted::FluxSlot;

/// A source measure with its averaged copies and flux field, built on first use and shared by
/// clones (module docs).
#[derive(Clone, Debug)]
pub struct PreparedMeasure {
    measure: Arc<SourceMeasure>,
    /// Averaged copies by sample size (`None`: averaging declined for that size).
    averaged: Arc<Mutex<Vec<AveragedCopy>>>,
    /// The flux form's field (`None` inside: the form declines the measure).
    flux: FluxSlot,
}

/// An averaged copy: the sample size asked for and the copy (`None`: averaging declined).
type AveragedCopy = (usize, Option<Arc<PreparedMeasure>>);

impl PreparedMeasure {
    /// Prepares `measure` (nothing is built until a solve asks for it).
    pub fn new(measure: SourceMeasure) -> Self {
        PreparedMeasure {
            measure: Arc::new(measure),
            averaged: Arc::default(),
            flux: Arc::default(),
        }
    }

    /// The measure.
    pub fn measure(&self) -> &SourceMeasure {
        &self.measure
    }

    /// The measure averaged over the Delaunay triangulation of about `sample` of its vertices
    /// ([`crate::averaging::averaged_measure`]), built on the first call for this sample size and
    /// kept; `None` where averaging declines. Concurrent callers wait for one build.
    pub fn averaged(&self, sample: usize) -> Option<Arc<PreparedMeasure>> {
        let mut copies = self.averaged.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some((_, copy)) = copies.iter().find(|(s, _)| *s == sample) {
            return copy.clone();
        }
        let copy = crate::averaging::averaged_measure(&self.measure, sample).map(|m| Arc::new(PreparedMeasure::new(m)));
        copies.push((sample, copy.clone()));
        copy
    }

    /// The sample sizes of the averaged copies built so far (for reports and tests).
    pub fn averaged_samples(&self) -> Vec<usize> {
        let copies = self.averaged.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        copies.iter().filter(|(_, c)| c.is_some()).map(|(s, _)| *s).collect()
    }

    /// The slot of the flux field, for the integrators of this measure.
    pub(crate) fn flux_slot(&self) -> FluxSlot {
        self.flux.clone()
    }
}

impl From<SourceMeasure> for PreparedMeasure {
    fn from(measure: SourceMeasure) -> Self {
        PreparedMeasure::new(measure)
    }
}

impl std::ops::Deref for PreparedMeasure {
    type Target = SourceMeasure;

    fn deref(&self) -> &SourceMeasure {
        &self.measure
    }
}
