//! The update of a diagram by flips from a previous one ([`super::DiagramBuilder::update_from`]).

use rayon::prelude::*;

use super::triangulator::{EdgeRepair, Triangulator};
use super::{Construction, InsertionOrder, PowerDiagram, NONE};
use crate::predicates::Weight;

impl PowerDiagram {
    /// The flip update of [`DiagramBuilder::update_from`]; None when stuck.
    pub(super) fn by_flips(
        &self,
        weights: Vec<Weight>,
        order: &InsertionOrder,
        max_hidden: usize,
    ) -> Option<Construction> {
        let n = self.sites.len();
        let inf = n as u32;
        let mut builder = Triangulator::new(
            &self.sites,
            &weights,
            self.triangle_vertices.clone(),
            self.triangle_neighbors.clone(),
            self.hidden.clone(),
        );
        let slots = builder.tv.len();
        // The edges that are not locally regular now (each edge once, from its triangle of
        // smaller index; read-only, so in parallel). Every flip pushes the edges whose
        // triangles it changed, so every non-regular edge is on the stack until repaired.
        let mut stack: Vec<(u32, u8)> = {
            let b = &builder;
            (0..slots as u32)
                .into_par_iter()
                .with_min_len(4096)
                .flat_map_iter(|t| {
                    let tri = b.tv[t as usize];
                    (0..3u8)
                        .filter(move |&k| {
                            tri[0] != NONE
                                && t < b.tn[t as usize][k as usize]
                                && b.edge_is_regular(t, k as usize) != Some(true)
                        })
                        .map(move |k| (t, k))
                })
                .collect()
        };
        let mut hidden_now = Vec::new();
        let mut deferred = Vec::new();
        // Each flip lowers the lifted surface, so none repeats; the cap only bounds the work
        // before falling back to the construction.
        let flip_cap = 8 * n + 64;
        let mut flips = 0usize;
        loop {
            let before = flips;
            while let Some((t, k)) = stack.pop() {
                match builder.restore_edge(t, k as usize, &mut stack, &mut hidden_now) {
                    EdgeRepair::Regular => {}
                    EdgeRepair::Flipped => {
                        flips += 1;
                        if flips > flip_cap {
                            return None;
                        }
                    }
                    EdgeRepair::Blocked => deferred.push((t, k)),
                    EdgeRepair::Degenerate => return None,
                }
                if hidden_now.len() > max_hidden {
                    // Hidden by a 3-1 flip means above the lifted plane of three sites around
                    // it: hidden in the regular triangulation too.
                    return Some(Construction::Hidden {
                        hidden: hidden_now,
                        inserted: n,
                    });
                }
            }
            if deferred.is_empty() {
                break;
            }
            if flips == before {
                return None;
            }
            stack.append(&mut deferred);
        }
        // The triangulation is now the regular one of its vertices; the previously hidden sites
        // are inserted (in insertion order, for short walks) and stay hidden unless in conflict.
        builder.last = (0..builder.tv.len() as u32).find(|&t| builder.tv[t as usize][0] != NONE)?;
        for &q in &order.order {
            if self.hidden[q as usize] {
                builder.hidden[q as usize] = false;
                builder.insert(q);
            }
        }
        let hidden_count = builder.hidden.iter().filter(|&&h| h).count();
        if hidden_count > max_hidden {
            return Some(Construction::Hidden {
                hidden: (0..n as u32).filter(|&i| builder.hidden[i as usize]).collect(),
                inserted: n,
            });
        }
        let Triangulator { tv, tn, hidden, .. } = builder;
        let mut vertex_triangle = vec![NONE; n];
        for (t, tri) in tv.iter().enumerate() {
            if tri[0] == NONE {
                continue;
            }
            for &v in tri {
                if v != inf {
                    vertex_triangle[v as usize] = t as u32;
                }
            }
        }
        // A visible site has a triangle and a hidden one none (else: a bug; rebuild).
        if (0..n).any(|v| hidden[v] != (vertex_triangle[v] == NONE)) {
            return None;
        }
        let mut diagram = PowerDiagram {
            sites: self.sites.clone(),
            weights,
            hidden: Vec::new(),
            neighbor_offsets: Vec::new(),
            neighbor_list: Vec::new(),
            dimension: 2,
            triangle_vertices: Vec::new(),
            triangle_neighbors: Vec::new(),
            start_site: 0,
        };
        diagram.set_triangulation(&order.order, tv, tn, hidden, vertex_triangle);
        Some(Construction::Complete(diagram))
    }
}
