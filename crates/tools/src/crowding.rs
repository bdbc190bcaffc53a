//! Nearest-neighbour distances of a point set from its Delaunay edges (shared by the crowding
//! probes).

use shapespace_omt::power_diagram::PowerDiagram;

/// For each point, the distance to its nearest neighbour (the shortest Delaunay edge at it),
/// and the Delaunay triangulation (a power diagram with zero weights) it came from.
pub fn nearest_neighbour_distances(y: &[[f64; 2]]) -> (Vec<f64>, PowerDiagram) {
    let pd = PowerDiagram::new(y, &vec![0.0; y.len()]).unwrap();
    let nn = (0..y.len())
        .map(|i| {
            pd.neighbors(i)
                .iter()
                .map(|&j| (y[i][0] - y[j as usize][0]).hypot(y[i][1] - y[j as usize][1]))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    (nn, pd)
}
