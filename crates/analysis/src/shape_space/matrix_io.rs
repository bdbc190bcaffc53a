//! Distance matrices and shape labels: types and CSV I/O.
//!
//! Distance matrix CSV (square, one row per shape, in the same order as the header):
//!
//! ```text
//! name,face01,face02,face03
//! face01,0,0.031,0.094
//! face02,0.0312,0,
//! face03,0.094,NaN,0
//! ```
//!
//! An empty cell or `NaN` (any case) is a missing distance (a failed pair). Entries need not be
//! symmetric: `d[i][j]` is the distance computed from shape `i` to shape `j`. Whitespace around
//! cells is ignored.
//!
//! Labels CSV: a header whose first column is `file` or `name`, then any number of label
//! columns; one row per shape, e.g.
//!
//! ```text
//! file,identity,expression
//! scans/face01.obj,p1,neutral
//! ```
//!
//! A row matches a shape when its key equals the shape name; else a key that is a file path
//! matches the shape whose name it ends with at a folder boundary, with or without its
//! extension, the longest such name (`scans/face01.obj` matches the shape `face01` or
//! `face01.obj`, `data/x/cat.obj` the shape `x/cat` beside `y/cat`); else equal file stems
//! decide, when only one shape has that stem. An empty label cell means "unknown" (module
//! `stats`).

use std::collections::HashMap;
use std::path::Path;

use serde::{Deserialize, Serialize};
use shapespace_geometry::io::AtomicFile;

use crate::error::AnalysisError;

/// A square matrix of distances between named shapes.
///
/// `values` is row-major with `names.len()²` entries: `values[i * n + j]` is the distance from
/// shape `i` to shape `j`. Missing entries are `NaN`; present entries are finite and `>= 0`.
/// The diagonal is stored as given and ignored by MDS and the statistics (a shape is never its
/// own neighbour; its self-distance is taken as 0).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DistanceMatrix {
    pub names: Vec<String>,
    pub values: Vec<f64>,
}

impl DistanceMatrix {
    /// Builds a matrix from names and row-major values (`#names²` entries, `NaN` = missing).
    ///
    /// Errors: [`AnalysisError::NotSquare`] if the sizes disagree, [`AnalysisError::DuplicateName`],
    /// [`AnalysisError::InvalidDistance`] for negative or infinite entries.
    pub fn new(names: Vec<String>, values: Vec<f64>) -> Result<Self, AnalysisError> {
        let n = names.len();
        if values.len() != n * n {
            return Err(AnalysisError::NotSquare {
                rows: n,
                cols: values.len().checked_div(n).unwrap_or(values.len()),
            });
        }
        let mut seen = HashMap::with_capacity(n);
        for name in &names {
            if seen.insert(name.as_str(), ()).is_some() {
                return Err(AnalysisError::DuplicateName { name: name.clone() });
            }
        }
        for i in 0..n {
            for j in 0..n {
                let v = values[i * n + j];
                if !v.is_nan() && (v < 0.0 || v.is_infinite()) {
                    return Err(AnalysisError::InvalidDistance {
                        a: names[i].clone(),
                        b: names[j].clone(),
                        value: v,
                    });
                }
            }
        }
        Ok(DistanceMatrix { names, values })
    }

    /// Builds a matrix from rows (`#names` rows of `#names` entries each, `NaN` = missing).
    pub fn from_rows(names: Vec<String>, rows: &[Vec<f64>]) -> Result<Self, AnalysisError> {
        let n = names.len();
        if rows.len() != n {
            return Err(AnalysisError::NotSquare {
                rows: rows.len(),
                cols: n,
            });
        }
        let mut values = Vec::with_capacity(n * n);
        for row in rows {
            if row.len() != n {
                return Err(AnalysisError::NotSquare {
                    rows: n,
                    cols: row.len(),
                });
            }
            values.extend_from_slice(row);
        }
        Self::new(names, values)
    }

    /// Number of shapes.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True when the matrix has no shapes.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// The stored distance from shape `i` to shape `j` (`NaN` if missing).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.values[i * self.names.len() + j]
    }

    /// The symmetric distance used by MDS and the statistics: the mean `(d_ij + d_ji)/2` when
    /// both directions are present, the present one when only one is, `NaN` when neither is;
    /// 0 on the diagonal.
    pub fn symmetric(&self, i: usize, j: usize) -> f64 {
        if i == j {
            return 0.0;
        }
        let (a, b) = (self.get(i, j), self.get(j, i));
        match (a.is_nan(), b.is_nan()) {
            (false, false) => 0.5 * (a + b),
            (false, true) => a,
            (true, false) => b,
            (true, true) => f64::NAN,
        }
    }

    /// The symmetrized matrix (see [`DistanceMatrix::symmetric`]), row-major `n²` entries.
    pub fn symmetrized_values(&self) -> Vec<f64> {
        let n = self.len();
        let mut out = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                out[i * n + j] = self.symmetric(i, j);
            }
        }
        out
    }

    /// The largest complete sub-matrix this greedy rule finds, and the names dropped: while an
    /// unordered pair has neither direction, drop the shape with the most such pairs (of equal
    /// counts, the later one). A shape that failed (an empty row and column) goes first; a
    /// complete matrix is returned whole. The kept shapes stay in their order.
    pub fn complete_subset(&self) -> (DistanceMatrix, Vec<String>) {
        let n = self.len();
        let mut kept: Vec<bool> = vec![true; n];
        loop {
            let mut missing = vec![0usize; n];
            for (i, j) in self.missing_pairs() {
                if kept[i] && kept[j] {
                    missing[i] += 1;
                    missing[j] += 1;
                }
            }
            let worst = (0..n).filter(|&i| missing[i] > 0).max_by_key(|&i| (missing[i], i));
            match worst {
                Some(i) => kept[i] = false,
                None => break,
            }
        }
        let keep: Vec<usize> = (0..n).filter(|&i| kept[i]).collect();
        let dropped = (0..n).filter(|&i| !kept[i]).map(|i| self.names[i].clone()).collect();
        let values = keep
            .iter()
            .flat_map(|&i| keep.iter().map(move |&j| (i, j)))
            .map(|(i, j)| self.get(i, j))
            .collect();
        let names = keep.iter().map(|&i| self.names[i].clone()).collect();
        (
            DistanceMatrix::new(names, values).expect("a square sub-matrix of distinct names"),
            dropped,
        )
    }

    /// Unordered pairs `{i, j}`, `i < j`, for which both directions are missing.
    pub fn missing_pairs(&self) -> Vec<(usize, usize)> {
        let n = self.len();
        let mut out = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                if self.symmetric(i, j).is_nan() {
                    out.push((i, j));
                }
            }
        }
        out
    }
}

/// Formats a distance so that it reads back exactly: plain decimal for moderate magnitudes,
/// scientific notation otherwise; `NaN` becomes an empty cell.
fn format_distance(v: f64) -> String {
    if v.is_nan() {
        String::new()
    } else if v == 0.0 || (1e-4..1e15).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Writes `d` as the square CSV described in the module docs (header `name,<names>`, one row
/// per shape, missing entries as empty cells). Values round-trip exactly.
pub fn write_distance_matrix(path: &Path, d: &DistanceMatrix) -> Result<(), AnalysisError> {
    let file = AtomicFile::create(path).map_err(|e| AnalysisError::io(path, e))?;
    let mut w = csv::Writer::from_writer(file);
    let mut header = Vec::with_capacity(d.len() + 1);
    header.push("name".to_string());
    header.extend(d.names.iter().cloned());
    w.write_record(&header).map_err(|e| AnalysisError::csv(path, e))?;
    for (i, name) in d.names.iter().enumerate() {
        let mut row = Vec::with_capacity(d.len() + 1);
        row.push(name.clone());
        row.extend((0..d.len()).map(|j| format_distance(d.get(i, j))));
        w.write_record(&row).map_err(|e| AnalysisError::csv(path, e))?;
    }
    w.into_inner()
        .map_err(|e| AnalysisError::io(path, e.into_error()))?
        .commit()
        .map_err(|e| AnalysisError::io(path, e))
}

fn parse_distance(cell: &str) -> Option<f64> {
    if cell.is_empty() || cell.eq_ignore_ascii_case("nan") {
        Some(f64::NAN)
    } else {
        cell.parse::<f64>().ok()
    }
}

/// Reads a square distance matrix CSV (module docs). Row `i` must name the `i`-th header shape.
///
/// Errors carry `path:line`: wrong number of cells, row names out of order, unparsable,
/// negative or infinite numbers, duplicate names, an empty file.
pub fn read_distance_matrix(path: &Path) -> Result<DistanceMatrix, AnalysisError> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| AnalysisError::csv(path, e))?;
    let mut records = reader.records();
    let header = match records.next() {
        Some(r) => r.map_err(|e| AnalysisError::csv(path, e))?,
        None => {
            return Err(AnalysisError::parse(
                path,
                1,
                "empty file, expected a header row `name,<name1>,...`",
            ))
        }
    };
    let header_line = header.position().map(|p| p.line()).unwrap_or(1);
    let names: Vec<String> = header.iter().skip(1).map(str::to_string).collect();
    if names.is_empty() {
        return Err(AnalysisError::parse(path, header_line, "header has no shape names"));
    }
    let mut first_line = HashMap::new();
    for name in &names {
        if name.is_empty() {
            return Err(AnalysisError::parse(path, header_line, "empty shape name in header"));
        }
        if first_line.insert(name.as_str(), ()).is_some() {
            return Err(AnalysisError::parse(
                path,
                header_line,
                format!("duplicate shape name {name:?} in header"),
            ));
        }
    }
    let n = names.len();
    let mut values = Vec::with_capacity(n * n);
    let mut rows = 0usize;
    for record in records {
        let record = record.map_err(|e| AnalysisError::csv(path, e))?;
        let line = record.position().map(|p| p.line()).unwrap_or(0);
        if record.iter().all(str::is_empty) {
            continue;
        }
        if rows == n {
            return Err(AnalysisError::parse(
                path,
                line,
                format!("more rows than the {n} shapes named in the header"),
            ));
        }
        if record.len() != n + 1 {
            return Err(AnalysisError::parse(
                path,
                line,
                format!(
                    "expected {} cells (name and {n} distances), found {}",
                    n + 1,
                    record.len()
                ),
            ));
        }
        let row_name = &record[0];
        if row_name != names[rows] {
            return Err(AnalysisError::parse(
                path,
                line,
                format!("row {} is named {row_name:?} but the header's shape {} is {:?} (rows must follow the header order)", rows + 1, rows + 1, names[rows]),
            ));
        }
        for (j, cell) in record.iter().skip(1).enumerate() {
            let v = parse_distance(cell).ok_or_else(|| {
                AnalysisError::parse(
                    path,
                    line,
                    format!("column {:?}: cannot parse {cell:?} as a number", names[j]),
                )
            })?;
            if !v.is_nan() && (v < 0.0 || v.is_infinite()) {
                return Err(AnalysisError::parse(
                    path,
                    line,
                    format!("column {:?}: distance {v} must be finite and >= 0", names[j]),
                ));
            }
            values.push(v);
        }
        rows += 1;
    }
    if rows != n {
        return Err(AnalysisError::parse(
            path,
            header_line,
            format!("header names {n} shapes but the file has {rows} rows"),
        ));
    }
    DistanceMatrix::new(names, values)
}

/// Label columns for the shapes of a distance matrix, aligned with its names.
///
/// `values[i][c]` is the value of column `columns[c]` for shape `i`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Labels {
    pub columns: Vec<String>,
    pub values: Vec<Vec<String>>,
    /// Shapes without a row in the file: their cells are empty (unknown).
    pub unlabeled: Vec<String>,
}

impl Labels {
    /// The rows of the shapes at `indices`, in that order.
    pub fn subset(&self, indices: &[usize], names: &[String]) -> Labels {
        Labels {
            columns: self.columns.clone(),
            values: indices.iter().map(|&i| self.values[i].clone()).collect(),
            unlabeled: self.unlabeled.iter().filter(|n| names.contains(n)).cloned().collect(),
        }
    }

    /// Index of a column by name.
    pub fn column_index(&self, column: &str) -> Result<usize, AnalysisError> {
        self.columns
            .iter()
            .position(|c| c == column)
            .ok_or_else(|| AnalysisError::UnknownLabelColumn {
                column: column.to_string(),
                available: self.columns.clone(),
            })
    }

    /// The values of one column, one per shape.
    pub fn column(&self, column: &str) -> Result<Vec<&str>, AnalysisError> {
        let c = self.column_index(column)?;
        Ok(self.values.iter().map(|row| row[c].as_str()).collect())
    }

    /// Number of shapes (rows).
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }
}

fn file_stem(s: &str) -> &str {
    // Works on both separators so that Windows-style paths in a CSV still match.
    let base = s.rsplit(['/', '\\']).next().unwrap_or(s);
    match base.rfind('.') {
        Some(k) if k > 0 => &base[..k],
        _ => base,
    }
}

/// Reads a labels CSV (module docs) and aligns it with `names` (the shapes of a distance
/// matrix). Matching: exact key; else the longest shape name the key ends with at a folder
/// boundary (with or without its extension); else equal file stems, when one shape has that
/// stem. Rows that match no shape are ignored.
///
/// Errors: header whose first column is not `file`/`name`, rows with the wrong number of cells
/// (`path:line`), a shape matched by two rows ([`AnalysisError::AmbiguousLabel`]). Shapes
/// without a row get empty cells (unknown, like an empty cell) and are listed in
/// [`Labels::unlabeled`].
pub fn read_labels(path: &Path, names: &[String]) -> Result<Labels, AnalysisError> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| AnalysisError::csv(path, e))?;
    let mut records = reader.records();
    let header = match records.next() {
        Some(r) => r.map_err(|e| AnalysisError::csv(path, e))?,
        None => {
            return Err(AnalysisError::parse(
                path,
                1,
                "empty file, expected a header row `file,<label columns>`",
            ))
        }
    };
    let header_line = header.position().map(|p| p.line()).unwrap_or(1);
    let key_col = header.get(0).unwrap_or("");
    if !(key_col.eq_ignore_ascii_case("file") || key_col.eq_ignore_ascii_case("name")) {
        return Err(AnalysisError::parse(
            path,
            header_line,
            format!("first column must be `file` or `name`, found {key_col:?}"),
        ));
    }
    let columns: Vec<String> = header.iter().skip(1).map(str::to_string).collect();
    for (k, c) in columns.iter().enumerate() {
        if c.is_empty() || columns[..k].contains(c) {
            return Err(AnalysisError::parse(
                path,
                header_line,
                format!("empty or duplicate label column name {c:?}"),
            ));
        }
    }

    let exact: HashMap<&str, usize> = names.iter().enumerate().map(|(i, n)| (n.as_str(), i)).collect();
    let mut by_stem: HashMap<&str, Vec<usize>> = HashMap::new();
    for (i, n) in names.iter().enumerate() {
        by_stem.entry(file_stem(n)).or_default().push(i);
    }
    // A key that is a file path names the shape whose name it ends with (at a folder boundary),
    // with or without the file's extension, the longest such name: `data/x/cat.obj` names
    // `x/cat` beside `y/cat`, `dots/p.a.ply` names `p.a`. Only when no name does, equal file
    // stems decide, and only for a stem one shape has.
    let path_match = |key: &str| -> Option<usize> {
        let key = key.replace('\\', "/");
        let without_extension = match key.rfind('.') {
            Some(k) if k > key.rfind('/').map_or(0, |s| s + 1) => &key[..k],
            _ => key.as_str(),
        };
        let ends_with = |whole: &str, name: &str| {
            whole == name
                || (whole.len() > name.len()
                    && whole.ends_with(name)
                    && whole[..whole.len() - name.len()].ends_with('/'))
        };
        names
            .iter()
            .enumerate()
            .filter(|(_, n)| ends_with(without_extension, n) || ends_with(&key, n))
            .max_by_key(|(_, n)| n.len())
            .map(|(i, _)| i)
    };
    let mut rows: Vec<Option<(u64, Vec<String>)>> = vec![None; names.len()];
    for record in records {
        let record = record.map_err(|e| AnalysisError::csv(path, e))?;
        let line = record.position().map(|p| p.line()).unwrap_or(0);
        if record.iter().all(str::is_empty) {
            continue;
        }
        if record.len() != columns.len() + 1 {
            return Err(AnalysisError::parse(
                path,
                line,
                format!("expected {} cells, found {}", columns.len() + 1, record.len()),
            ));
        }
        let key = &record[0];
        let matched: Vec<usize> = match exact.get(key).copied().or_else(|| path_match(key)) {
            Some(i) => vec![i],
            None => by_stem
                .get(file_stem(key))
                .filter(|shapes| shapes.len() == 1)
                .cloned()
                .unwrap_or_default(),
        };
        for i in matched {
            if let Some((first_line, _)) = &rows[i] {
                return Err(AnalysisError::AmbiguousLabel {
                    path: path.to_path_buf(),
                    line,
                    key: key.to_string(),
                    name: names[i].clone(),
                    first_line: *first_line,
                });
            }
            rows[i] = Some((line, record.iter().skip(1).map(str::to_string).collect()));
        }
    }
    let missing: Vec<String> = rows
        .iter()
        .zip(names)
        .filter(|(r, _)| r.is_none())
        .map(|(_, n)| n.clone())
        .collect();
    let width = columns.len();
    Ok(Labels {
        columns,
        values: rows
            .into_iter()
            .map(|r| r.map(|(_, v)| v).unwrap_or_else(|| vec![String::new(); width]))
            .collect(),
        unlabeled: missing,
    })
}
