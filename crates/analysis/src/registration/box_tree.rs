//! A bounding-volume hierarchy over the axis-aligned boxes of triangles, in the plane or in
//! space: the candidates of the point locators ([`crate::point_location::PointLocator`] in a
//! disk image, [`crate::registration::sphere::SphereLocator`] on S²). Built top-down by the
//! median of the box centres along a split axis, leaves of at most [`LEAF_CAPACITY`] boxes:
//! exactly 2⌈F/leaf⌉ − 1 nodes whatever the geometry.

/// Largest number of boxes in a leaf.
pub const LEAF_CAPACITY: usize = 8;

#[derive(Clone, Copy, Debug)]
struct Node<const D: usize> {
    lo: [f64; D],
    hi: [f64; D],
    /// Leaf: `items[start..end]`; inner: children `start` and `end` (node indices).
    start: usize,
    end: usize,
    leaf: bool,
}

/// The hierarchy over boxes `(lo, hi)` indexed 0..F.
#[derive(Clone, Debug)]
pub(crate) struct BoxTree<const D: usize> {
    nodes: Vec<Node<D>>,
    items: Vec<u32>,
}

impl<const D: usize> BoxTree<D> {
    /// The hierarchy over `boxes`; each node splits along `split_axis(lo, hi)` of its box.
    pub(crate) fn new(boxes: &[([f64; D], [f64; D])], split_axis: fn(&[f64; D], &[f64; D]) -> usize) -> Self {
        let mut tree = BoxTree {
            nodes: Vec::with_capacity(2 * boxes.len() / LEAF_CAPACITY + 2),
            items: (0..boxes.len() as u32).collect(),
        };
        if !boxes.is_empty() {
            tree.build(0, boxes.len(), boxes, split_axis);
        }
        tree
    }

    /// Builds the node over `items[start..end]` and returns its index.
    fn build(
        &mut self,
        start: usize,
        end: usize,
        boxes: &[([f64; D], [f64; D])],
        split_axis: fn(&[f64; D], &[f64; D]) -> usize,
    ) -> usize {
        let mut lo = [f64::INFINITY; D];
        let mut hi = [f64::NEG_INFINITY; D];
        for &t in &self.items[start..end] {
            let (bl, bh) = boxes[t as usize];
            for k in 0..D {
                lo[k] = lo[k].min(bl[k]);
                hi[k] = hi[k].max(bh[k]);
            }
        }
        let id = self.nodes.len();
        self.nodes.push(Node {
            lo,
            hi,
            start,
            end,
            leaf: true,
        });
        if end - start <= LEAF_CAPACITY {
            return id;
        }
        let axis = split_axis(&lo, &hi);
        let mid = start + (end - start) / 2;
        let centre = |t: &u32| boxes[*t as usize].0[axis] + boxes[*t as usize].1[axis];
        self.items[start..end].select_nth_unstable_by(mid - start, |a, b| centre(a).total_cmp(&centre(b)));
        let left = self.build(start, mid, boxes, split_axis);
        let right = self.build(mid, end, boxes, split_axis);
        self.nodes[id] = Node {
            lo,
            hi,
            start: left,
            end: right,
            leaf: false,
        };
        id
    }

    /// Calls `visit` for every box that contains `p` (a leaf's boxes in their stored order, the
    /// second child before the first).
    pub(crate) fn for_candidates(&self, p: [f64; D], mut visit: impl FnMut(u32)) {
        if self.nodes.is_empty() {
            return;
        }
        // the tree is balanced (median splits): its depth is at most log2(#nodes) + 1, so a
        // fixed stack of 2 · 64 entries never overflows
        let mut stack = [0usize; 128];
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let nd = &self.nodes[stack[len]];
            if !(0..D).all(|k| p[k] >= nd.lo[k] && p[k] <= nd.hi[k]) {
                continue;
            }
            if nd.leaf {
                for &t in &self.items[nd.start..nd.end] {
                    visit(t);
                }
            } else {
                stack[len] = nd.start;
                stack[len + 1] = nd.end;
                len += 2;
            }
        }
    }
}
