//! `shapespace._native`: the Rust side of the `shapespace` Python package (PyO3). Thin wrappers
//! of the library functions the command-line tool calls; the Python module `shapespace`
//! (`python/shapespace/__init__.py`) gives them their documented signatures. Arrays cross as
//! numpy arrays (float64 coordinates, uint32 faces), reports as JSON text. Every heavy call runs
//! with the GIL released; library errors become `shapespace.ShapespaceError` with the message
//! the command-line tool prints.

use std::collections::{HashMap, HashSet};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use shapespace_analysis::distance::{matrix_from_pairs, pairwise_distances_of, PairRecord, PairwiseOptions};
use shapespace_analysis::invariance::Invariance;
use shapespace_analysis::pipeline::{
    prepare_inputs, shape_names, DistancesOptions, Domain as RunDomain, MarkerOptions,
};
use shapespace_conformal::{BoundaryMarker, CenterMarker, Markers};
use shapespace_geometry::TriMesh;
use shapespace_omt::{solve_ot, NewtonParams, SourceMeasure};

create_exception!(
    _native,
    ShapespaceError,
    PyException,
    "An error of shapespace: bad input (the message names the file or argument) or a failed computation."
);

fn error(e: impl std::fmt::Display) -> PyErr {
    ShapespaceError::new_err(e.to_string())
}

type Points2<'py> = Bound<'py, PyArray2<f64>>;

/// n × k rows as a numpy array.
fn rows<'py, const K: usize, T: numpy::Element + Copy>(py: Python<'py>, rows: &[[T; K]]) -> Bound<'py, PyArray2<T>> {
    let flat: Vec<T> = rows.iter().flatten().copied().collect();
    Array2::from_shape_vec((rows.len(), K), flat)
        .expect("n × K values")
        .into_pyarray(py)
}

/// The rows of an n × K array (C or Fortran order, any strides).
fn from_rows<T: numpy::Element + Copy, const K: usize>(
    a: &PyReadonlyArray2<'_, T>,
    what: &str,
) -> PyResult<Vec<[T; K]>> {
    let shape = a.shape();
    if shape[1] != K {
        return Err(error(format!(
            "{what}: expected an array of shape (n, {K}), got {shape:?}"
        )));
    }
    let view = a.as_array();
    Ok(view.rows().into_iter().map(|r| std::array::from_fn(|k| r[k])).collect())
}

fn mesh_from(v: PyReadonlyArray2<'_, f64>, f: PyReadonlyArray2<'_, u32>) -> PyResult<TriMesh> {
    TriMesh::new(from_rows(&v, "V")?, from_rows(&f, "F")?).map_err(error)
}

fn markers_from(center: Option<&str>, boundary: Option<&str>) -> PyResult<Markers> {
    let mut markers = Markers::default();
    if let Some(c) = center {
        markers.center = CenterMarker::parse(c).map_err(error)?;
    }
    if let Some(b) = boundary {
        markers.boundary = BoundaryMarker::parse(b).map_err(error)?;
    }
    Ok(markers)
}

fn json(value: &impl serde::Serialize) -> PyResult<String> {
    serde_json::to_string(value).map_err(error)
}

/// `(V, F)` of a mesh file (OBJ, OFF, PLY).
#[pyfunction]
fn read_mesh<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Points2<'py>, Bound<'py, PyArray2<u32>>)> {
    let mesh = py.detach(|| shapespace_geometry::io::read_mesh(&path)).map_err(error)?;
    Ok((rows(py, &mesh.positions), rows(py, &mesh.faces)))
}

/// The mesh report of `shapespace info` (JSON) and its classification.
#[pyfunction]
fn info(py: Python<'_>, v: PyReadonlyArray2<'_, f64>, f: PyReadonlyArray2<'_, u32>) -> PyResult<String> {
    let mesh = mesh_from(v, f)?;
    py.detach(|| -> PyResult<String> {
        let report = shapespace_geometry::topology::mesh_report(&mesh).map_err(error)?;
        let class = shapespace_geometry::topology::classify_report(&report);
        json(&serde_json::json!({ "report": report, "classification": class }))
    })
}

/// The conformal map onto the unit disk: (uv, log conformal factors, report JSON).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn conformal_map<'py>(
    py: Python<'py>,
    v: PyReadonlyArray2<'_, f64>,
    f: PyReadonlyArray2<'_, u32>,
    center: Option<String>,
    boundary: Option<String>,
    method: &str,
    pole: &str,
    intrinsic_delaunay: bool,
    bff_fallback: bool,
) -> PyResult<(Points2<'py>, Bound<'py, PyArray1<f64>>, String)> {
    let mesh = mesh_from(v, f)?;
    let markers = markers_from(center.as_deref(), boundary.as_deref())?;
    let method = method.to_string();
    let pole = match pole {
        "center" => shapespace_conformal::PolePlacement::AtCenter,
        "central" => shapespace_conformal::PolePlacement::Central,
        other => return Err(error(format!("pole {other:?}: expected \"center\" or \"central\""))),
    };
    let (uv, factor, report) = py.detach(|| -> PyResult<_> {
        shapespace_geometry::topology::require_disk(&mesh)
            .map_err(|e| error(format!("the mesh is not usable for a disk map: {e}")))?;
        let context = |e: &dyn std::fmt::Display| error(format!("conformal map: {e}"));
        match method.as_str() {
            "green" => {
                let params = shapespace_conformal::DiskMapParams {
                    intrinsic_delaunay,
                    pole,
                    bff_fallback,
                    // without the fallback: the Green's-function construction alone
                    region_repair: bff_fallback,
                    ..Default::default()
                };
                let map = shapespace_conformal::disk_map(&mesh, &markers, &params).map_err(|e| context(&e))?;
                let report = serde_json::json!({
                    "method": map.info.method.to_string(), "scale": map.scale, "info": map.info,
                    "quality": map.quality, "center": map.info.markers.center,
                    "boundary": map.info.markers.boundary_vertex,
                });
                Ok((map.uv, map.conformal_factor, report))
            }
            "bff" => {
                let params = shapespace_conformal::BffParams {
                    intrinsic_delaunay,
                    ..Default::default()
                };
                let map = shapespace_conformal::bff_disk_map(&mesh, &markers, &params).map_err(|e| context(&e))?;
                let report = serde_json::json!({
                    "method": map.info.method.clone(), "scale": map.scale, "info": map.info,
                    "quality": map.quality, "center": map.info.markers.center,
                    "boundary": map.info.markers.boundary_vertex,
                });
                Ok((map.uv, map.conformal_factor, report))
            }
            other => Err(error(format!("method {other:?}: expected \"green\" or \"bff\""))),
        }
    })?;
    Ok((rows(py, &uv), Array1::from(factor).into_pyarray(py), json(&report)?))
}

/// The area-preserving map by optimal transport: (uv, report JSON).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn area_preserving_map<'py>(
    py: Python<'py>,
    v: PyReadonlyArray2<'_, f64>,
    f: PyReadonlyArray2<'_, u32>,
    center: Option<String>,
    boundary: Option<String>,
    domain: &str,
    tolerance: f64,
    fold_repair: bool,
) -> PyResult<(Points2<'py>, String)> {
    use shapespace_analysis::area_preserving::{area_preserving_map as map_of, AreaPreservingParams, Domain};
    let mesh = mesh_from(v, f)?;
    let markers = markers_from(center.as_deref(), boundary.as_deref())?;
    let domain: Domain = domain.parse().map_err(error)?;
    let (uv, report) = py.detach(|| -> PyResult<_> {
        shapespace_geometry::topology::require_disk(&mesh)
            .map_err(|e| error(format!("the mesh is not usable for a disk parameterization: {e}")))?;
        let mut params = AreaPreservingParams {
            domain,
            require_convergence: false,
            ..Default::default()
        };
        params.newton.tolerance = tolerance;
        params.fold_repair.enabled = fold_repair;
        let map = map_of(&mesh, &markers, &params).map_err(error)?;
        let distortion =
            shapespace_analysis::distortion::distortion_report(&mesh, &map.conformal.uv, &map.uv).map_err(error)?;
        let report = serde_json::json!({
            "ot": map.ot, "timings": map.timings, "fold_repair": map.fold_repair.info,
            "distortion": distortion, "square_rotation": map.square_rotation,
        });
        Ok((map.uv, report))
    })?;
    Ok((rows(py, &uv), json(&report)?))
}

/// Semi-discrete OT from a source density to weighted points: (heights, cell masses,
/// centroids, report JSON).
#[pyfunction]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn ot<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'_, f64>,
    masses: PyReadonlyArray1<'_, f64>,
    domain: &str,
    density_uv: Option<PyReadonlyArray2<'_, f64>>,
    density_faces: Option<PyReadonlyArray2<'_, u32>>,
    densities: Option<PyReadonlyArray1<'_, f64>>,
    tol: f64,
    max_iterations: usize,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Points2<'py>,
    String,
)> {
    let points: Vec<[f64; 2]> = from_rows(&points, "points")?;
    let masses: Vec<f64> = masses.as_array().to_vec();
    let measure = match (density_uv, density_faces) {
        (Some(uv), Some(faces)) => {
            let faces: Vec<[u32; 3]> = from_rows(&faces, "density_mesh faces")?;
            let densities = match densities {
                Some(d) => d.as_array().to_vec(),
                None => vec![1.0; faces.len()],
            };
            let measure =
                SourceMeasure::new(from_rows(&uv, "density_mesh vertices")?, faces, densities).map_err(error)?;
            let gap = measure.convexity_gap();
            if !(gap.abs() <= 1e-6) {
                return Err(error(format!(
                    "density_mesh: the triangles do not tile a convex domain (they miss {gap:.2e} of their convex hull's area{})",
                    if gap < 0.0 { ": they overlap" } else { "" }
                )));
            }
            measure
        }
        _ => match domain {
            "disk" => SourceMeasure::unit_disk(512).map_err(error)?,
            "square" => SourceMeasure::unit_square().map_err(error)?,
            other => return Err(error(format!("domain {other:?}: expected \"disk\" or \"square\""))),
        },
    };
    if points.len() != masses.len() {
        return Err(error(format!("{} points and {} masses", points.len(), masses.len())));
    }
    let params = NewtonParams {
        tolerance: tol,
        max_iterations,
        ..NewtonParams::default()
    };
    let (solution, centroids) = py.detach(|| -> PyResult<_> {
        let solution = solve_ot(&measure, &points, &masses, &params).map_err(error)?;
        let centroids: Vec<[f64; 2]> = solution
            .centroids()
            .into_iter()
            .map(|c| c.unwrap_or([f64::NAN, f64::NAN]))
            .collect();
        Ok((solution, centroids))
    })?;
    let report = serde_json::json!({
        "cost": solution.cost, "dual_cost": solution.dual_value(), "iterations": solution.iterations,
        "evaluations": solution.evaluations, "max_relative_error": solution.max_relative_error,
        "status": solution.stop_description(), "converged": solution.converged(),
    });
    Ok((
        Array1::from(solution.heights.clone()).into_pyarray(py),
        Array1::from(solution.cells.masses.clone()).into_pyarray(py),
        rows(py, &centroids),
        json(&report)?,
    ))
}

/// The settings of a pairwise run, as the `distances` command takes them.
#[derive(Clone, Debug, FromPyObject)]
struct Settings {
    center: Option<String>,
    boundary: Option<String>,
    landmarks: Option<PathBuf>,
    symmetrize: bool,
    tol: Option<f64>,
    max_iterations: Option<usize>,
    invariance: String,
    target_points: Option<usize>,
    pair_time_limit: Option<f64>,
    domain: String,
    sphere_markers: Option<Vec<u32>>,
    source_faces: Option<usize>,
}

impl Settings {
    /// The options the command builds from the same flags (`cmd/distances.rs`).
    fn options(&self) -> PyResult<DistancesOptions> {
        let defaults = PairwiseOptions::default().newton;
        let tol = self.tol.unwrap_or(defaults.tolerance);
        let max_iterations = self.max_iterations.unwrap_or(defaults.max_iterations);
        if !(tol > 0.0 && tol < 1.0) {
            return Err(error(format!(
                "tol must be in (0, 1) (a relative mass error per cell), got {tol}"
            )));
        }
        if max_iterations < 1 {
            return Err(error("max_iterations must be at least 1"));
        }
        if self.target_points == Some(0) {
            return Err(error("target_points must be at least 1"));
        }
        if self.source_faces == Some(0) {
            return Err(error("source_faces must be at least 1"));
        }
        let time_limit = self
            .pair_time_limit
            .map(|s| {
                std::time::Duration::try_from_secs_f64(s)
                    .ok()
                    .filter(|d| !d.is_zero())
                    .ok_or_else(|| error(format!("pair_time_limit must be a positive number of seconds, got {s}")))
            })
            .transpose()?;
        Ok(DistancesOptions {
            markers: MarkerOptions {
                center: self
                    .center
                    .as_deref()
                    .map(CenterMarker::parse)
                    .transpose()
                    .map_err(error)?,
                boundary: self
                    .boundary
                    .as_deref()
                    .map(BoundaryMarker::parse)
                    .transpose()
                    .map_err(error)?,
                marker_file: self.landmarks.clone(),
                sphere_markers: match &self.sphere_markers {
                    None => None,
                    Some(v) if v.len() == 3 => Some([v[0], v[1], v[2]]),
                    Some(v) => {
                        return Err(error(format!(
                            "sphere_markers: expected 3 vertex indices, got {}",
                            v.len()
                        )))
                    }
                },
            },
            pairwise: PairwiseOptions {
                symmetrize: self.symmetrize,
                newton: NewtonParams {
                    tolerance: tol,
                    max_iterations,
                    ..defaults
                },
                time_limit,
                invariance: match self.invariance.as_str() {
                    "fixed" => Invariance::Fixed,
                    "rotation" => Invariance::Rotation,
                    other => {
                        return Err(error(format!(
                            "invariance {other:?}: expected \"fixed\" or \"rotation\""
                        )))
                    }
                },
                ..PairwiseOptions::default()
            },
            target_points: self.target_points,
            source_faces: self.source_faces,
            domain: match self.domain.as_str() {
                "auto" => RunDomain::Auto,
                "disk" => RunDomain::Disk,
                "sphere" => RunDomain::Sphere,
                other => {
                    return Err(error(format!(
                        "domain {other:?}: expected \"auto\", \"disk\" or \"sphere\""
                    )))
                }
            },
            ..DistancesOptions::default()
        })
    }
}

/// A pair's record as a tuple: (a, b, source, target, distance, cost, iterations,
/// max_mass_error, seconds, status, evaluations, dual_cost).
type RecordTuple = (
    String,
    String,
    usize,
    usize,
    f64,
    f64,
    usize,
    f64,
    f64,
    String,
    usize,
    f64,
);

fn record_tuple(r: &PairRecord) -> RecordTuple {
    (
        r.a.clone(),
        r.b.clone(),
        r.source,
        r.target,
        r.distance,
        r.cost,
        r.iterations,
        r.max_mass_error,
        r.seconds,
        r.status.clone(),
        r.evaluations,
        r.dual_cost,
    )
}

/// Shape names of the inputs; the same name twice is an error.
fn names_of(paths: &[PathBuf]) -> PyResult<Vec<String>> {
    let names = shape_names(paths);
    let mut seen = HashMap::new();
    for (i, name) in names.iter().enumerate() {
        if let Some(j) = seen.insert(name.clone(), i) {
            return Err(error(format!(
                "{} and {} are the same file or have the same shape name \"{name}\"",
                paths[j].display(),
                paths[i].display()
            )));
        }
    }
    Ok(names)
}

fn meshes_from(
    meshes: Option<Vec<(PyReadonlyArray2<'_, f64>, PyReadonlyArray2<'_, u32>)>>,
) -> PyResult<Option<Vec<TriMesh>>> {
    meshes
        .map(|m| {
            m.into_iter()
                .map(|(v, f)| mesh_from(v, f))
                .collect::<PyResult<Vec<_>>>()
        })
        .transpose()
}

/// The shapes of a pairwise run, prepared once (read, markers shared as `shapespace distances`
/// shares them, conformal maps, densities): the per-shape stage of the command. Its pairs are
/// computed by [`Prepared::pairs`], all of them or a tile, with the GIL released.
#[pyclass(module = "shapespace._native", frozen)]
struct Prepared {
    names: Vec<String>,
    options: DistancesOptions,
    shapes: Vec<Option<shapespace_analysis::distance::Prepared>>,
    inputs: String,
    warnings: Vec<String>,
}

#[pymethods]
impl Prepared {
    /// Prepares the shapes of `paths` (with `meshes`, those meshes, which `paths` then only
    /// name) with the settings of a pairwise run.
    #[new]
    #[pyo3(signature = (paths, meshes, settings))]
    fn new(
        py: Python<'_>,
        paths: Vec<PathBuf>,
        meshes: Option<Vec<(PyReadonlyArray2<'_, f64>, PyReadonlyArray2<'_, u32>)>>,
        settings: Settings,
    ) -> PyResult<Self> {
        let options = settings.options()?;
        if paths.len() < 2 {
            return Err(error(format!("distances need at least 2 shapes, got {}", paths.len())));
        }
        let names = names_of(&paths)?;
        let meshes = meshes_from(meshes)?;
        let prepared = py
            .detach(|| prepare_inputs(&paths, meshes.as_deref(), &names, &options, &|_, _, _| {}))
            .map_err(error)?;
        Ok(Prepared {
            names,
            options,
            inputs: json(&prepared.inputs)?,
            warnings: prepared.marker_warnings,
            shapes: prepared.shapes,
        })
    }

    /// Each shape's prepared data as bytes (None where it failed): what Dask workers receive.
    /// Closed surfaces (the sphere) have no byte form yet: an error.
    fn shape_bytes<'py>(&self, py: Python<'py>) -> PyResult<Vec<Option<Bound<'py, pyo3::types::PyBytes>>>> {
        let figures = shapespace_analysis::shape_cache::CachedFigures {
            flipped_faces: 0,
            bff_fallback_after_green_folds: None,
        };
        self.shapes
            .iter()
            .map(|s| {
                s.as_ref()
                    .map(|s| match s.as_disk() {
                        Some(s) => Ok(pyo3::types::PyBytes::new(
                            py,
                            &shapespace_analysis::shape_cache::encode(s, &figures),
                        )),
                        None => Err(error(
                            "closed surfaces (the sphere) cannot be sent to Dask workers yet: run their pairs without a client",
                        )),
                    })
                    .transpose()
            })
            .collect()
    }

    /// The shapes of [`Prepared::shape_bytes`] (on a worker), under `names`, with the settings of
    /// the run that prepared them.
    #[staticmethod]
    fn from_shape_bytes(names: Vec<String>, shapes: Vec<Option<Vec<u8>>>, settings: Settings) -> PyResult<Self> {
        let options = settings.options()?;
        if names.len() != shapes.len() {
            return Err(error(format!("{} names and {} shapes", names.len(), shapes.len())));
        }
        let shapes = shapes
            .iter()
            .zip(&names)
            .map(|(bytes, name)| {
                bytes
                    .as_ref()
                    .map(|b| {
                        shapespace_analysis::shape_cache::decode(b, name)
                            .map(|(shape, _)| shapespace_analysis::distance::Prepared::Disk(Box::new(shape)))
                            .ok_or_else(|| error(format!("{name}: damaged prepared-shape data")))
                    })
                    .transpose()
            })
            .collect::<PyResult<Vec<_>>>()?;
        Ok(Prepared {
            names,
            options,
            shapes,
            inputs: "[]".into(),
            warnings: Vec::new(),
        })
    }

    /// The shape names (as `distances.csv` names them).
    #[getter]
    fn names(&self) -> Vec<String> {
        self.names.clone()
    }

    /// Each input's report (report.json's `inputs`), JSON.
    #[getter]
    fn inputs(&self) -> String {
        self.inputs.clone()
    }

    /// Warnings about automatic markers (report.json's `marker_warnings`).
    #[getter]
    fn marker_warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// Whether each shape was prepared (False: its file failed; its pairs fail).
    #[getter]
    fn ok(&self) -> Vec<bool> {
        self.shapes.iter().map(Option::is_some).collect()
    }

    /// The records of the directed pairs (source, target) of `pairs` (all pairs of the run when
    /// None), in the run's order (by target, then source).
    #[pyo3(signature = (pairs=None))]
    fn pairs(&self, py: Python<'_>, pairs: Option<Vec<(usize, usize)>>) -> PyResult<Vec<RecordTuple>> {
        let n = self.names.len();
        if let Some((s, t)) = pairs.iter().flatten().find(|(s, t)| *s >= n || *t >= n || s == t) {
            return Err(error(format!("pair ({s}, {t}): not two different shapes among {n}")));
        }
        Ok(py.detach(|| {
            let only: Option<HashSet<(usize, usize)>> = pairs.map(|p| p.into_iter().collect());
            let stop = AtomicBool::new(false);
            let result = pairwise_distances_of(
                &self.shapes,
                &self.options.pairwise,
                only.as_ref(),
                &HashMap::new(),
                &stop,
                &|_| {},
            );
            result
                .pairs
                .iter()
                .map(|r| PairRecord {
                    a: self.names[r.source].clone(),
                    b: self.names[r.target].clone(),
                    ..r.clone()
                })
                .map(|r| record_tuple(&r))
                .collect()
        }))
    }
}

/// The matrix of a run from its directed pairs (source, target, distance) over n shapes whose
/// `ok` flags are given ([`matrix_from_pairs`]), and the relative asymmetries.
#[pyfunction]
#[allow(clippy::type_complexity)]
fn matrix_of_pairs<'py>(
    py: Python<'py>,
    ok: Vec<bool>,
    pairs: Vec<(usize, usize, f64)>,
    symmetrize: bool,
) -> PyResult<(Points2<'py>, Vec<f64>)> {
    let n = ok.len();
    if let Some((s, t, _)) = pairs.iter().find(|(s, t, _)| *s >= n || *t >= n) {
        return Err(error(format!("pair ({s}, {t}): not among {n} shapes")));
    }
    let records: Vec<PairRecord> = pairs
        .into_iter()
        .map(|(source, target, distance)| PairRecord {
            a: String::new(),
            b: String::new(),
            source,
            target,
            distance,
            cost: f64::NAN,
            iterations: 0,
            max_mass_error: f64::NAN,
            seconds: 0.0,
            status: String::new(),
            evaluations: 0,
            dual_cost: f64::NAN,
        })
        .collect();
    let (matrix, asymmetries, _) = matrix_from_pairs(&ok, &records, symmetrize, None);
    Ok((
        Array2::from_shape_vec((n, n), matrix).expect("n × n").into_pyarray(py),
        asymmetries,
    ))
}

/// The directed pairs of shard `index` of `count` over n shapes (`distances --shard`).
#[pyfunction]
fn shard_pairs(n: usize, symmetrize: bool, index: usize, count: usize) -> PyResult<Vec<(usize, usize)>> {
    if index == 0 || index > count {
        return Err(error(format!("shard {index}/{count}: expected 1 <= index <= count")));
    }
    Ok(shapespace_analysis::shard::Shard { index, count }.pairs(n, symmetrize))
}

/// Classical MDS: (coordinates n × dims, all eigenvalues).
#[pyfunction]
#[allow(clippy::type_complexity)]
fn mds<'py>(
    py: Python<'py>,
    d: PyReadonlyArray2<'_, f64>,
    dims: usize,
) -> PyResult<(Points2<'py>, Bound<'py, PyArray1<f64>>, String)> {
    let shape = d.shape();
    let n = shape[0];
    if shape[1] != n {
        return Err(error(format!("D: expected a square matrix, got shape {shape:?}")));
    }
    let values: Vec<f64> = d.as_array().iter().copied().collect();
    let names = (0..n).map(|i| i.to_string()).collect();
    let result = py.detach(|| -> PyResult<_> {
        let matrix = shapespace_analysis::DistanceMatrix::new(names, values).map_err(error)?;
        shapespace_analysis::classical_mds(&matrix, dims).map_err(error)
    })?;
    let flat: Vec<f64> = result.coordinates.iter().flatten().copied().collect();
    let coordinates = Array2::from_shape_vec((n, dims), flat).map_err(error)?.into_pyarray(py);
    let report = serde_json::json!({
        "variance_shares": result.variance_shares, "positive_sum": result.positive_sum,
        "negative_sum": result.negative_sum, "negative_count": result.negative_count,
    });
    Ok((
        coordinates,
        Array1::from(result.eigenvalues).into_pyarray(py),
        json(&report)?,
    ))
}

/// The version of the Rust crates.
#[pyfunction]
fn version() -> &'static str {
    env!("CARGO_PKG_VERSION")
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ShapespaceError", m.py().get_type::<ShapespaceError>())?;
    m.add_function(wrap_pyfunction!(read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(info, m)?)?;
    m.add_function(wrap_pyfunction!(conformal_map, m)?)?;
    m.add_function(wrap_pyfunction!(area_preserving_map, m)?)?;
    m.add_function(wrap_pyfunction!(ot, m)?)?;
    m.add_class::<Prepared>()?;
    m.add_function(wrap_pyfunction!(matrix_of_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(shard_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(mds, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    Ok(())
}
