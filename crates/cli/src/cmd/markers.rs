//! The marker options shared by `conformal`, `param`, `distances` and `demo`.

use std::path::{Path, PathBuf};

use anyhow::Result;
use shapespace_analysis::pipeline::{markers_for, MarkerOptions};
use shapespace_conformal::{BoundaryMarker, CenterMarker, Markers};

/// Interior marker p ↦ 0 and boundary marker q ↦ 1 of the disk maps.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct MarkerArgs {
    /// Interior marker p ↦ 0: a vertex index, a point `x,y,z` (projected to the surface) or
    /// `auto` (the vertex farthest from the boundary). Overrides the marker file.
    #[arg(long)]
    pub center: Option<String>,
    /// Boundary marker q ↦ 1: a boundary vertex index or `auto` (the boundary vertex farthest
    /// from the center). Overrides the marker file.
    #[arg(long = "boundary-marker")]
    pub boundary_marker: Option<String>,
    /// Marker file `{"center": .., "boundary": .., "landmarks": {..}}` for every input (default:
    /// the sidecar NAME.landmarks.json, else landmarks.json beside each input, else `auto`).
    #[arg(long)]
    pub landmarks: Option<PathBuf>,
}

impl MarkerArgs {
    /// The parsed options (parse errors name the offending flag).
    pub fn options(&self) -> Result<MarkerOptions> {
        Ok(MarkerOptions {
            center: self.center.as_deref().map(CenterMarker::parse).transpose()?,
            boundary: self.boundary_marker.as_deref().map(BoundaryMarker::parse).transpose()?,
            marker_file: self.landmarks.clone(),
            sphere_markers: None,
        })
    }

    /// The markers of the mesh file `path` of `num_vertices` vertices (flags, then marker file,
    /// then sidecar, then auto) and where they came from (the marker file's path, or `auto`).
    pub fn resolve(&self, path: &Path, num_vertices: usize) -> Result<(Markers, String)> {
        Ok(markers_for(path, &self.options()?, num_vertices)?)
    }
}
