//! Probe: how the choice of the interior marker changes the crowding of a disk map.
//! `cargo run --release -p shapespace-tools --bin center_probe -- MESH [K]`: maps MESH
//! with K interior vertices (evenly spaced by index) as centre and prints, per centre, Ok with
//! the smallest 1 − |z| over interior vertices and the smallest nearest-edge image length, or
//! the error.
use shapespace_conformal::{disk_map, BoundaryMarker, CenterMarker, DiskMapParams, Markers};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mesh = shapespace_geometry::io::read_mesh(std::path::Path::new(&args[1])).unwrap();
    let k: usize = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(40);
    let conn = shapespace_geometry::Connectivity::of(&mesh);
    let on_b = conn.boundary_vertices(mesh.num_vertices());
    let interior: Vec<u32> = (0..mesh.num_vertices() as u32).filter(|&v| !on_b[v as usize]).collect();
    let mut rows = Vec::new();
    for s in 0..k {
        let v = interior[s * interior.len() / k];
        let markers = Markers {
            center: CenterMarker::Vertex(v),
            boundary: BoundaryMarker::Auto,
        };
        match disk_map(&mesh, &markers, &DiskMapParams::default()) {
            Ok(m) => {
                let gap = (0..mesh.num_vertices())
                    .filter(|&i| !on_b[i])
                    .map(|i| 1.0 - m.uv[i][0].hypot(m.uv[i][1]))
                    .fold(f64::INFINITY, f64::min);
                let mut emin = f64::INFINITY;
                for f in &mesh.faces {
                    for e in 0..3 {
                        let (a, b) = (m.uv[f[e] as usize], m.uv[f[(e + 1) % 3] as usize]);
                        emin = emin.min((a[0] - b[0]).hypot(a[1] - b[1]));
                    }
                }
                rows.push(format!(
                    "center {v}: ok, min 1-|z| {gap:.2e}, min image edge {emin:.2e}, repairs {}",
                    m.info.fold_repairs
                ));
            }
            Err(e) => rows.push(format!("center {v}: {e}")),
        }
    }
    for r in rows {
        println!("{r}");
    }
}
