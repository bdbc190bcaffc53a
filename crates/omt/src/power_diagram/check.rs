//! The structural invariants of a diagram, checked with exact predicates (tests and fuzzing).

use super::triangulator::Triangulator;
use super::{PowerDiagram, NONE};
use crate::predicates::{orient, power_side_1d};

impl PowerDiagram {
    /// Checks every structural invariant with exact predicates: triangles counter-clockwise and
    /// adjacency symmetric, every edge locally regular (the opposite vertex is not in conflict,
    /// hull convex), the triangle count 2V − 2 of a sphere (with the infinite vertex), hidden
    /// sites exactly those in no triangle and truly redundant, neighbour lists symmetric and equal
    /// to the triangulation's edges. Local regularity everywhere implies the triangulation is
    /// the regular one. Err(description) on the first violation.
    pub fn sanity_check(&self) -> Result<(), String> {
        let n = self.sites.len();
        for i in 0..n {
            if self.hidden[i] && !self.neighbors(i).is_empty() {
                return Err(format!("hidden site {i} has neighbours"));
            }
            for &j in self.neighbors(i) {
                if j as usize >= n || j as usize == i {
                    return Err(format!("site {i} has invalid neighbour {j}"));
                }
                if !self.neighbors(j as usize).contains(&(i as u32)) {
                    return Err(format!("neighbour lists not symmetric: {j} ∈ N({i}) but {i} ∉ N({j})"));
                }
            }
        }
        match self.dimension {
            0 => {
                if n != 1 || self.hidden[0] {
                    return Err("dimension 0 needs exactly one visible site".into());
                }
                Ok(())
            }
            1 => self.sanity_check_collinear(),
            _ => self.sanity_check_2d(),
        }
    }

    fn sanity_check_collinear(&self) -> Result<(), String> {
        let (s, w) = (&self.sites, &self.weights);
        let n = s.len();
        for k in 2..n {
            if orient(s[0], s[1], s[k]) != 0 {
                return Err(format!("dimension 1 but site {k} is off the line of sites 0, 1"));
            }
        }
        let mut along: Vec<usize> = (0..n).collect();
        along.sort_unstable_by(|&i, &j| s[i][0].total_cmp(&s[j][0]).then(s[i][1].total_cmp(&s[j][1])));
        let chain: Vec<usize> = along.iter().copied().filter(|&i| !self.hidden[i]).collect();
        if chain.len() < 2 || chain[0] != along[0] || chain[chain.len() - 1] != along[n - 1] {
            return Err("the extreme sites of a line must be visible".into());
        }
        for k in 0..chain.len() {
            let mut expected = Vec::new();
            if k > 0 {
                expected.push(chain[k - 1] as u32);
            }
            if k + 1 < chain.len() {
                expected.push(chain[k + 1] as u32);
            }
            if self.neighbors(chain[k]) != expected.as_slice() {
                return Err(format!("site {} should have neighbours {expected:?}", chain[k]));
            }
        }
        for win in chain.windows(3) {
            let (a, b, c) = (win[0], win[1], win[2]);
            if !power_side_1d(s[a], w[a], a as u32, s[c], w[c], c as u32, s[b], w[b], b as u32) {
                return Err(format!("site {b} is visible but redundant between {a} and {c}"));
            }
        }
        let mut k = 0;
        for &h in &along {
            if !self.hidden[h] {
                k += 1;
                continue;
            }
            let (a, c) = (chain[k - 1], chain[k]);
            if power_side_1d(s[a], w[a], a as u32, s[c], w[c], c as u32, s[h], w[h], h as u32) {
                return Err(format!(
                    "site {h} is hidden but in conflict with its segment ({a}, {c})"
                ));
            }
        }
        Ok(())
    }

    fn sanity_check_2d(&self) -> Result<(), String> {
        let n = self.sites.len();
        let inf = n as u32;
        let tv = &self.triangle_vertices;
        let tn = &self.triangle_neighbors;
        let mut builder = Triangulator::new(&self.sites, &self.weights, tv.clone(), tn.clone(), self.hidden.clone());
        builder.rng = 0x9E37_79B9;
        let mut in_triangle = vec![false; n];
        let mut alive = 0usize;
        let mut any_alive = NONE;
        let mut edge_count = 0usize;
        for (t, tri) in tv.iter().enumerate() {
            if tri[0] == NONE {
                continue;
            }
            alive += 1;
            any_alive = t as u32;
            if tri.iter().any(|&v| v > inf) || tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                return Err(format!("triangle {t} has invalid vertices {tri:?}"));
            }
            for &v in tri {
                if v != inf {
                    if self.hidden[v as usize] {
                        return Err(format!("hidden site {v} is a vertex of triangle {t}"));
                    }
                    in_triangle[v as usize] = true;
                }
            }
            if !tri.contains(&inf) {
                let [a, b, c] = tri.map(|v| self.sites[v as usize]);
                if orient(a, b, c) <= 0 {
                    return Err(format!("triangle {t} {tri:?} is not counter-clockwise"));
                }
            }
            for k in 0..3 {
                let s = tn[t][k];
                if s as usize >= tv.len() || tv[s as usize][0] == NONE {
                    return Err(format!("triangle {t} has a dead or invalid neighbour {s}"));
                }
                let (u, v) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                let other = tv[s as usize];
                let Some(j) = (0..3).find(|&j| tn[s as usize][j] == t as u32) else {
                    return Err(format!("adjacency not symmetric between triangles {t} and {s}"));
                };
                if other[(j + 1) % 3] != v || other[(j + 2) % 3] != u {
                    return Err(format!(
                        "triangles {t} and {s} do not share edge ({u}, {v}) in opposite orientation"
                    ));
                }
                let d = other[j];
                if d != inf && builder.conflict(t as u32, d) {
                    return Err(format!(
                        "edge ({u}, {v}) is not regular: site {d} is in conflict with triangle {tri:?}"
                    ));
                }
                if u != inf && v != inf && !self.neighbors(u as usize).contains(&v) {
                    return Err(format!("edge ({u}, {v}) missing from the neighbour lists"));
                }
                if u != inf && v != inf {
                    edge_count += 1;
                }
                // Collinear consecutive hull edges: the middle vertex must not be redundant.
                if tri.contains(&inf) && other.contains(&inf) && (u == inf || v == inf) {
                    let rot = |tr: [u32; 3]| {
                        let p = tr.iter().position(|&x| x == inf).unwrap_or(0);
                        (tr[(p + 1) % 3], tr[(p + 2) % 3])
                    };
                    let (a, b) = rot(*tri);
                    let (b2, c) = rot(other);
                    let (a, b, c) = if b == b2 { (a, b, c) } else { (b2, c, b) };
                    let (pa, pb, pc) = (self.sites[a as usize], self.sites[b as usize], self.sites[c as usize]);
                    let o = orient(pa, pb, pc);
                    if b == b2 && o > 0 {
                        return Err(format!("hull not convex at site {b}"));
                    }
                    if b == b2 && o == 0 {
                        let w = &self.weights;
                        let ok = power_side_1d(pa, w[a as usize], a, pc, w[c as usize], c, pb, w[b as usize], b);
                        if !ok {
                            return Err(format!("collinear hull site {b} is visible but redundant"));
                        }
                    }
                }
            }
        }
        let visible = (0..n).filter(|&i| !self.hidden[i]).count();
        if alive != 2 * visible - 2 {
            return Err(format!(
                "{alive} triangles for {visible} visible sites (expected {})",
                2 * visible - 2
            ));
        }
        if edge_count != self.neighbor_list.len() {
            return Err(format!(
                "{} directed neighbour entries but {edge_count} directed finite edges",
                self.neighbor_list.len()
            ));
        }
        for i in 0..n {
            if !self.hidden[i] && !in_triangle[i] {
                return Err(format!("visible site {i} is in no triangle"));
            }
            if self.hidden[i] {
                let t = builder.locate(i as u32, any_alive);
                if builder.conflict(t, i as u32) {
                    return Err(format!(
                        "hidden site {i} is in conflict with triangle {:?}",
                        tv[t as usize]
                    ));
                }
            }
        }
        Ok(())
    }
}
