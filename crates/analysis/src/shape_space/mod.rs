//! The `shapespace mds` pipeline in one call: read a distance matrix (and labels), embed it with
//! classical MDS ([`crate::mds`]) or metric MDS by SMACOF ([`crate::mds::smacof`]), compute the statistics of [`crate::stats`], and write the
//! tables, plots and `stats.json` to an output directory. The submodules are the parts: distance
//! matrices and labels as CSV ([`matrix_io`]), MDS ([`mds`]) and statistics ([`stats`]). The
//! `mds` command.

pub mod matrix_io;
pub mod mds;
pub mod stats;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use shapespace_geometry::io::{write_atomically, AtomicFile};

use crate::error::AnalysisError;
use crate::matrix_io::{read_distance_matrix, read_labels, DistanceMatrix, Labels};
use crate::mds::smacof::{smacof_mds, stress, SmacofParams, Stress};
use crate::mds::{classical_mds, Mds};
use crate::plot::{mds_scatter, mds_scatter_matrix, ColorScale, ScatterLabels, MAX_MATRIX_AXES};
use crate::stats::{
    class_distances, loo_1nn_accuracy, loo_1nn_accuracy_across, mean_silhouette, symmetry_gap, triangle_violations,
    ClassDistances, NnAccuracy, SymmetryGap, TriangleViolations,
};

/// The embedding method of [`run_mds`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MdsMethod {
    /// Classical (Torgerson) MDS ([`classical_mds`]).
    #[default]
    Classical,
    /// Metric MDS minimizing the raw stress by SMACOF, started from the classical embedding
    /// ([`smacof_mds`]).
    Smacof,
}

/// Options of [`run_mds`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MdsParams {
    /// Classical MDS (default) or SMACOF.
    #[serde(default)]
    pub method: MdsMethod,
    /// Tolerance and iteration cap of SMACOF (read only with [`MdsMethod::Smacof`]).
    #[serde(default)]
    pub smacof: SmacofParams,
    /// Embedding dimension `k` (`1 <= k <= #shapes`); the plot shows the first two, and for
    /// k ≥ 3 a scatter matrix the first k (at most [`MAX_MATRIX_AXES`]).
    pub dims: usize,
    /// Label column giving the point colours; default: the first label column.
    pub color_by: Option<String>,
    /// Label column giving the marker shapes; default: the second label column, if any.
    pub marker_by: Option<String>,
    /// How the colour column becomes colours (numbers on a continuous scale by default).
    pub color_scale: ColorScale,
    /// Write each shape's name beside its point.
    pub point_labels: bool,
    /// Triangle-inequality tolerance relative to the mean distance: a triple violates when
    /// `d_ik > d_ij + d_jk + triangle_rel_eps · mean(d)`.
    pub triangle_rel_eps: f64,
    /// Label columns whose cross-column accuracies ([`CrossAccuracy`], one per ordered pair of
    /// distinct columns) `stats.json` gets; None: every column when there are at most
    /// [`MAX_CROSS_COLUMNS`], else none (the count is quadratic in the columns).
    pub cross_columns: Option<Vec<String>>,
}

/// The most label columns whose cross-column accuracies are computed without being asked for:
/// c columns give c(c − 1) of them (1,000 columns made a 176 MB `stats.json`).
pub const MAX_CROSS_COLUMNS: usize = 8;

impl Default for MdsParams {
    fn default() -> Self {
        MdsParams {
            method: MdsMethod::Classical,
            smacof: SmacofParams::default(),
            dims: 2,
            color_by: None,
            marker_by: None,
            color_scale: ColorScale::Auto,
            point_labels: false,
            triangle_rel_eps: 1e-9,
            cross_columns: None,
        }
    }
}

/// Statistics of one label column.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LabelColumnStats {
    /// Number of distinct values.
    pub classes: usize,
    /// Leave-one-out 1-NN accuracy ([`loo_1nn_accuracy`]).
    pub loo_1nn: NnAccuracy,
    /// Mean silhouette ([`mean_silhouette`]); `None` for a single class.
    pub silhouette: Option<f64>,
    /// Within/between-class distance summaries.
    pub distances: ClassDistances,
}

/// 1-NN accuracy of `target` when the neighbour must differ in `exclude_same`
/// ([`loo_1nn_accuracy_across`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CrossAccuracy {
    /// The label column predicted (e.g. `expression`).
    pub target: String,
    /// The column whose value the neighbour must not share with the query (e.g. `identity`).
    pub exclude_same: String,
    /// The accuracy.
    pub loo_1nn: NnAccuracy,
}

/// Summary of the embedding, for `stats.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MdsSummary {
    pub dims: usize,
    /// Share of variance of each embedding dimension.
    pub variance_shares: Vec<f64>,
    /// Σ of positive eigenvalues.
    pub positive_sum: f64,
    /// Σ |negative eigenvalues| / Σ positive eigenvalues (0 for Euclidean distances).
    pub negative_ratio: f64,
    /// Number of significantly negative eigenvalues.
    pub negative_count: usize,
    /// Embedding dimensions clamped to 0 (non-positive eigenvalue).
    pub clamped_dims: usize,
    /// The method of the embedding written.
    #[serde(default)]
    pub method: MdsMethod,
    /// Raw stress Σ_{i<j} (d_ij − |x_i − x_j|)² and Kruskal's stress-1 of the embedding written
    /// ([`stress`]).
    #[serde(default)]
    pub stress: Stress,
    /// The same of the classical embedding (equal to `stress` for the classical method).
    #[serde(default)]
    pub classical_stress: Stress,
    /// SMACOF's Guttman transforms (None for the classical method).
    #[serde(default)]
    pub smacof_iterations: Option<usize>,
    /// Whether SMACOF reached its tolerance (None for the classical method).
    #[serde(default)]
    pub smacof_converged: Option<bool>,
}

/// Everything written to `stats.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeSpaceStats {
    /// Number of shapes embedded.
    pub n: usize,
    /// Shapes of the matrix left out of the embedding and the statistics because some of their
    /// distances are missing ([`DistanceMatrix::complete_subset`]).
    pub dropped_shapes: Vec<String>,
    /// Embedded shapes without a row in the labels file (their labels are unknown).
    pub unlabeled_shapes: Vec<String>,
    /// Unordered pairs with neither direction present.
    pub missing_pairs: usize,
    pub symmetry: SymmetryGap,
    pub triangle: TriangleViolations,
    pub mds: MdsSummary,
    /// Per label column (sorted by name).
    pub labels: BTreeMap<String, LabelColumnStats>,
    /// For every ordered pair of distinct label columns among those chosen
    /// ([`MdsParams::cross_columns`]).
    pub cross: Vec<CrossAccuracy>,
    /// Why `cross` is empty although there are several label columns (more than
    /// [`MAX_CROSS_COLUMNS`] and none chosen).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cross_skipped: Option<String>,
}

/// The result of [`run_mds`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MdsResult {
    /// Shape names, in matrix order.
    pub names: Vec<String>,
    pub mds: Mds,
    pub stats: ShapeSpaceStats,
    /// Label columns used for colours and markers.
    pub color_by: Option<String>,
    pub marker_by: Option<String>,
    /// Files written.
    #[serde(serialize_with = "crate::report_path::many")]
    pub files: Vec<PathBuf>,
}

/// Computes the statistics of `d` (and of `labels`, aligned with it, if given) for `stats.json`;
/// the cross-column accuracies among `cross_columns` ([`MdsParams::cross_columns`]).
pub fn shape_space_stats(
    d: &DistanceMatrix,
    labels: Option<&Labels>,
    mds: &Mds,
    triangle_rel_eps: f64,
    cross_columns: Option<&[String]>,
) -> Result<ShapeSpaceStats, AnalysisError> {
    let embedding_stress = stress(d, &mds.coordinates)?;
    let symmetry = symmetry_gap(d);
    let eps = triangle_rel_eps * symmetry.mean_distance.unwrap_or(0.0);
    let triangle = triangle_violations(d, eps);
    let mut label_stats = BTreeMap::new();
    let mut cross = Vec::new();
    let mut cross_skipped = None;
    if let Some(labels) = labels {
        for col in &labels.columns {
            let classes = crate::stats::label_classes(&labels.column(col)?);
            label_stats.insert(
                col.clone(),
                LabelColumnStats {
                    classes: classes.len(),
                    loo_1nn: loo_1nn_accuracy(d, labels, col)?,
                    silhouette: mean_silhouette(d, labels, col)?,
                    distances: class_distances(d, labels, col)?,
                },
            );
        }
        let chosen: Vec<String> = match cross_columns {
            Some(columns) => {
                for column in columns {
                    labels.column_index(column)?;
                }
                columns.to_vec()
            }
            None if labels.columns.len() <= MAX_CROSS_COLUMNS => labels.columns.clone(),
            None => {
                cross_skipped = Some(format!(
                    "{} label columns, more than {MAX_CROSS_COLUMNS}: cross-column accuracies only for the columns asked for (--cross-columns)",
                    labels.columns.len()
                ));
                Vec::new()
            }
        };
        for target in &chosen {
            for exclude in &chosen {
                if target != exclude {
                    cross.push(CrossAccuracy {
                        target: target.clone(),
                        exclude_same: exclude.clone(),
                        loo_1nn: loo_1nn_accuracy_across(d, labels, target, exclude)?,
                    });
                }
            }
        }
    }
    Ok(ShapeSpaceStats {
        n: d.len(),
        dropped_shapes: Vec::new(),
        unlabeled_shapes: Vec::new(),
        missing_pairs: d.missing_pairs().len(),
        symmetry,
        triangle,
        mds: MdsSummary {
            dims: mds.dims(),
            variance_shares: mds.variance_shares.clone(),
            positive_sum: mds.positive_sum,
            negative_ratio: if mds.positive_sum > 0.0 {
                mds.negative_sum / mds.positive_sum
            } else {
                0.0
            },
            negative_count: mds.negative_count,
            clamped_dims: mds.clamped_dims,
            method: MdsMethod::Classical,
            stress: embedding_stress,
            classical_stress: embedding_stress,
            smacof_iterations: None,
            smacof_converged: None,
        },
        labels: label_stats,
        cross,
        cross_skipped,
    })
}

fn write_csv(path: &Path, rows: impl IntoIterator<Item = Vec<String>>) -> Result<(), AnalysisError> {
    let to_err = |e: csv::Error| AnalysisError::csv(path, e);
    let file = AtomicFile::create(path).map_err(|e| AnalysisError::io(path, e))?;
    let mut w = csv::Writer::from_writer(file);
    for row in rows {
        w.write_record(&row).map_err(to_err)?;
    }
    w.into_inner()
        .map_err(|e| AnalysisError::io(path, e.into_error()))?
        .commit()
        .map_err(|e| AnalysisError::io(path, e))
}

/// Writes `mds.csv`: header `name,<label columns>,x1..xk`, one row per shape.
pub fn write_mds_csv(path: &Path, names: &[String], labels: Option<&Labels>, mds: &Mds) -> Result<(), AnalysisError> {
    let mut header = vec!["name".to_string()];
    if let Some(l) = labels {
        header.extend(l.columns.iter().cloned());
    }
    header.extend((1..=mds.dims()).map(|k| format!("x{k}")));
    let rows = names.iter().enumerate().map(|(i, name)| {
        let mut row = vec![name.clone()];
        if let Some(l) = labels {
            row.extend(l.values[i].iter().cloned());
        }
        row.extend(mds.coordinates[i].iter().map(|x| format!("{x}")));
        row
    });
    write_csv(path, std::iter::once(header).chain(rows))
}

/// Writes `eigenvalues.csv`: header `k,eigenvalue,share`, all eigenvalues in non-increasing
/// order, `share = λ_k / Σ_{λ>0} λ` (negative for negative eigenvalues).
pub fn write_eigenvalues_csv(path: &Path, mds: &Mds) -> Result<(), AnalysisError> {
    let header = vec!["k".to_string(), "eigenvalue".to_string(), "share".to_string()];
    let rows = mds
        .eigenvalues
        .iter()
        .zip(mds.eigenvalue_shares())
        .enumerate()
        .map(|(k, (l, s))| vec![(k + 1).to_string(), format!("{l}"), format!("{s}")]);
    write_csv(path, std::iter::once(header).chain(rows))
}

/// The files [`run_mds`] writes into its output folder.
pub const MDS_OUTPUTS: [&str; 7] = [
    "mds.csv",
    "eigenvalues.csv",
    "mds.png",
    "mds.svg",
    "stats.json",
    "mds_matrix.png",
    "mds_matrix.svg",
];

/// `shapespace mds`: reads the distance matrix CSV `distances` (and the labels CSV `labels`,
/// matched to the shapes as [`read_labels`] says), embeds it with classical MDS or SMACOF
/// (`params.method`) in `params.dims` dimensions, and writes to `out_dir` (created if needed):
///
/// - `mds.csv` (name, label columns, x1..xk), `eigenvalues.csv` (k, eigenvalue, share);
/// - `mds.png` and `mds.svg`: the first two coordinates, coloured by `color_by` and shaped by
///   `marker_by` (defaults: first and second label columns);
/// - `stats.json` ([`ShapeSpaceStats`]): symmetry gap, triangle-inequality violations, the MDS
///   variance summary, the embedding's raw stress and stress-1 (and the classical
///   embedding's, and SMACOF's iterations), and with labels per column 1-NN LOO accuracy, silhouette, within/between
///   distances, and the cross-column accuracies for every ordered pair of columns (of the
///   columns chosen, [`MdsParams::cross_columns`]: by default all of at most
///   [`MAX_CROSS_COLUMNS`], so that the file stays linear in the number of columns).
///
/// Errors before anything is written: unreadable or malformed CSVs, unknown label columns, a
/// missing distance (MDS needs a complete matrix; the error names the pair), invalid `dims`.
pub fn run_mds(
    distances: &Path,
    labels: Option<&Path>,
    out_dir: &Path,
    params: &MdsParams,
) -> Result<MdsResult, AnalysisError> {
    let full = read_distance_matrix(distances)?;
    let all_labels = labels.map(|p| read_labels(p, &full.names)).transpose()?;
    // shapes whose distances are missing (failed files or pairs) leave the embedding
    let (d, dropped) = full.complete_subset();
    let kept: Vec<usize> = (0..full.len()).filter(|&i| !dropped.contains(&full.names[i])).collect();
    let labels = all_labels.map(|l| l.subset(&kept, &d.names));
    if d.len() < 2 {
        return Err(AnalysisError::InvalidInput(format!(
            "{}: fewer than 2 shapes have all their distances (dropped: {})",
            distances.display(),
            dropped.join(", ")
        )));
    }
    let pick = |given: &Option<String>, default_index: usize, what: &str| -> Result<Option<String>, AnalysisError> {
        match (given, &labels) {
            (Some(col), Some(l)) => l.column_index(col).map(|_| Some(col.clone())),
            (Some(_), None) => Err(AnalysisError::LabelsRequired { what: what.to_string() }),
            (None, Some(l)) => Ok(l.columns.get(default_index).cloned()),
            (None, None) => Ok(None),
        }
    };
    let color_by = pick(&params.color_by, 0, "colouring by a label column")?;
    let marker_by = pick(&params.marker_by, 1, "choosing markers by a label column")?;

    let (mds, smacof) = match params.method {
        MdsMethod::Classical => (classical_mds(&d, params.dims)?, None),
        MdsMethod::Smacof => {
            let (mds, info) = smacof_mds(&d, params.dims, &params.smacof)?;
            (mds, Some(info))
        }
    };
    let mut stats = shape_space_stats(
        &d,
        labels.as_ref(),
        &mds,
        params.triangle_rel_eps,
        params.cross_columns.as_deref(),
    )?;
    if let Some(info) = &smacof {
        stats.mds.method = MdsMethod::Smacof;
        stats.mds.classical_stress = info.initial;
        stats.mds.smacof_iterations = Some(info.iterations);
        stats.mds.smacof_converged = Some(info.converged);
    }

    stats.dropped_shapes = dropped;
    stats.unlabeled_shapes = labels.as_ref().map(|l| l.unlabeled.clone()).unwrap_or_default();
    std::fs::create_dir_all(out_dir).map_err(|e| AnalysisError::io(out_dir, e))?;
    let [mds_name, eig_name, png_name, svg_name, json_name, matrix_png, matrix_svg] = MDS_OUTPUTS;
    let mut files = Vec::new();
    let mds_csv = out_dir.join(mds_name);
    write_mds_csv(&mds_csv, &d.names, labels.as_ref(), &mds)?;
    files.push(mds_csv);
    let eig_csv = out_dir.join(eig_name);
    write_eigenvalues_csv(&eig_csv, &mds)?;
    files.push(eig_csv);

    let column = |c: &Option<String>| -> Result<Option<(String, Vec<&str>)>, AnalysisError> {
        match (c, &labels) {
            (Some(c), Some(l)) => Ok(Some((c.clone(), l.column(c)?))),
            _ => Ok(None),
        }
    };
    let colors = column(&color_by)?;
    let markers = column(&marker_by)?;
    let source = distances
        .file_name()
        .map_or_else(|| distances.display().to_string(), |f| f.to_string_lossy().into_owned());
    let method = match params.method {
        MdsMethod::Classical => "Classical",
        MdsMethod::Smacof => "SMACOF",
    };
    let title = format!("{method} MDS of {source} (n = {})", d.len());
    let names: Vec<&str> = d.names.iter().map(String::as_str).collect();
    let scatter = ScatterLabels {
        color: colors.as_ref().map(|(c, v)| (c.as_str(), v.as_slice())),
        marker: markers.as_ref().map(|(c, v)| (c.as_str(), v.as_slice())),
        point_labels: params.point_labels.then_some(names.as_slice()),
        color_scale: params.color_scale,
    };
    for name in [png_name, svg_name] {
        let path = out_dir.join(name);
        mds_scatter(&path, &mds, &scatter, &title)?;
        files.push(path);
    }
    // k ≥ 3 axes: a scatter matrix of the first k; otherwise an earlier run's matrix, which
    // would show another embedding, is removed
    let k = params.dims.min(MAX_MATRIX_AXES);
    for name in [matrix_png, matrix_svg] {
        let path = out_dir.join(name);
        if k >= 3 {
            mds_scatter_matrix(&path, &mds, k, &scatter, &title)?;
            files.push(path);
        } else if path.exists() {
            std::fs::remove_file(&path).map_err(|e| AnalysisError::io(&path, e))?;
        }
    }
    let json_path = out_dir.join(json_name);
    let json = serde_json::to_string_pretty(&stats).map_err(|e| AnalysisError::Serialize {
        path: json_path.clone(),
        message: e.to_string(),
    })?;
    write_atomically(&json_path, (json + "\n").as_bytes()).map_err(|e| AnalysisError::io(&json_path, e))?;
    files.push(json_path);

    Ok(MdsResult {
        names: d.names,
        mds,
        stats,
        color_by,
        marker_by,
        files,
    })
}
