//! Landmark pairs of a registration: vertex l1_k on the source S₁ and its partner l2_k on the
//! target S₂, from a CSV file (`source,target` rows) or from the named landmarks of two marker
//! files (paired by name). [`Landmarks::validate`] checks them against both meshes.

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::AnalysisError;

/// Landmark pairs (source vertex, target vertex) with a name each (the marker name, or
/// `line N` for a CSV row) and the name of where they came from (for error messages).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Landmarks {
    /// (vertex of S₁, vertex of S₂) per landmark.
    pub pairs: Vec<(u32, u32)>,
    /// Name of each landmark (same length as `pairs`).
    pub names: Vec<String>,
    /// Where the landmarks came from (file path or a description).
    pub source_name: String,
}

fn lm_err(source: &str, name: &str, message: impl Into<String>) -> AnalysisError {
    AnalysisError::Landmark {
        source_name: source.to_string(),
        landmark: name.to_string(),
        message: message.into(),
    }
}

impl Landmarks {
    /// Landmarks from explicit pairs, named `0, 1, ...`.
    pub fn from_pairs(pairs: Vec<(u32, u32)>, source_name: &str) -> Self {
        let names = (0..pairs.len()).map(|k| k.to_string()).collect();
        Landmarks {
            pairs,
            names,
            source_name: source_name.to_string(),
        }
    }

    /// Reads a CSV file with rows `source,target` (0-based vertex indices; an optional header
    /// line in which no field is a number; `#` comments; a leading byte-order mark is skipped).
    /// Each landmark is named `line N`. Errors name the file and the line; a first row with
    /// one number and one typo is an error, not a header.
    pub fn from_csv(path: &Path) -> Result<Self, AnalysisError> {
        let text = std::fs::read_to_string(path).map_err(|e| AnalysisError::io(path, e))?;
        let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
        let src = path.display().to_string();
        let mut out = Landmarks {
            source_name: src.clone(),
            ..Default::default()
        };
        for (i, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let name = format!("line {}", i + 1);
            if out.pairs.is_empty()
                && out.names.is_empty()
                && fields.iter().all(|f| f.parse::<f64>().is_err())
                && i == first_content_line(text)
            {
                continue; // header
            }
            if fields.len() != 2 {
                return Err(AnalysisError::parse(
                    path,
                    i as u64 + 1,
                    format!("expected `source,target`, got {} fields", fields.len()),
                ));
            }
            let parse = |s: &str| {
                s.parse::<u32>().map_err(|_| {
                    lm_err(
                        &src,
                        &name,
                        format!("`{s}` is not a vertex index (a non-negative integer)"),
                    )
                })
            };
            out.pairs.push((parse(fields[0])?, parse(fields[1])?));
            out.names.push(name);
        }
        if out.pairs.is_empty() {
            return Err(lm_err(&src, "-", "no landmark pairs in the file"));
        }
        Ok(out)
    }

    /// Pairs the named landmarks of two marker files by name (sorted by name). Names present in
    /// only one file are an error (listing them); `source_name` describes the two files.
    pub fn from_named(
        source: &BTreeMap<String, u32>,
        target: &BTreeMap<String, u32>,
        source_name: &str,
    ) -> Result<Self, AnalysisError> {
        let only_source: Vec<&str> = source
            .keys()
            .filter(|k| !target.contains_key(*k))
            .map(String::as_str)
            .collect();
        let only_target: Vec<&str> = target
            .keys()
            .filter(|k| !source.contains_key(*k))
            .map(String::as_str)
            .collect();
        if let Some(first) = only_source.first().or(only_target.first()) {
            return Err(lm_err(
                source_name,
                first,
                format!(
                    "present in only one of the two landmark sets (source only: [{}], target only: [{}])",
                    only_source.join(", "),
                    only_target.join(", ")
                ),
            ));
        }
        let mut out = Landmarks {
            source_name: source_name.to_string(),
            ..Default::default()
        };
        for (name, &v) in source {
            out.pairs.push((v, target[name]));
            out.names.push(name.clone());
        }
        Ok(out)
    }

    /// Number of landmark pairs.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Whether there are no landmarks.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Checks the pairs against S₁ (#V = `n1`, boundary flags `boundary1`) and S₂: every index
    /// in range, no vertex used by two landmarks on the same side, no landmark on the boundary
    /// (the harmonic map pins the whole boundary to the circle, so a boundary landmark could not
    /// be honoured). Errors name the source and the landmark.
    pub fn validate(&self, boundary1: &[bool], boundary2: &[bool]) -> Result<(), AnalysisError> {
        if self.names.len() != self.pairs.len() {
            return Err(lm_err(&self.source_name, "-", "names and pairs differ in length"));
        }
        let mut seen1: BTreeMap<u32, &str> = BTreeMap::new();
        let mut seen2: BTreeMap<u32, &str> = BTreeMap::new();
        for ((a, b), name) in self.pairs.iter().zip(&self.names) {
            for (side, v, bnd, seen) in [
                ("source", *a, boundary1, &mut seen1),
                ("target", *b, boundary2, &mut seen2),
            ] {
                if v as usize >= bnd.len() {
                    return Err(lm_err(
                        &self.source_name,
                        name,
                        format!(
                            "{side} vertex {v} out of range (the {side} mesh has {} vertices)",
                            bnd.len()
                        ),
                    ));
                }
                if bnd[v as usize] {
                    return Err(lm_err(
                        &self.source_name,
                        name,
                        format!("{side} vertex {v} lies on the boundary (the boundary is mapped to the circle; use an interior vertex)"),
                    ));
                }
                if let Some(other) = seen.insert(v, name) {
                    return Err(lm_err(
                        &self.source_name,
                        name,
                        format!("{side} vertex {v} is also landmark {other}"),
                    ));
                }
            }
        }
        Ok(())
    }
}

fn first_content_line(text: &str) -> usize {
    text.lines()
        .position(|l| !l.split('#').next().unwrap_or("").trim().is_empty())
        .unwrap_or(0)
}
