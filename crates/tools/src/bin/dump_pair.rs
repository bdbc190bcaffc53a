//! Writes the OT problem of one face pair (source a's density, target b's points and masses) as
//! JSON, for the solver probes of `shapespace-omt` (`cargo run --release -p shapespace-tools --bin eval_probe -- pair FILE`), so they do not redo the conformal maps.
//!
//! `cargo run --release -p shapespace-tools --bin dump_pair -- A B OUT.json` (from the
//! repository root; default id00_sad id00_neutral).
use shapespace_tools::faces;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let a = args.get(1).cloned().unwrap_or("id00_sad".into());
    let b = args.get(2).cloned().unwrap_or("id00_neutral".into());
    let out = args.get(3).cloned().unwrap_or(format!("{a}_{b}.json"));
    let shapes = faces::prepared_faces(&[a.as_str(), b.as_str()]);
    let json = serde_json::json!({
        "vertices": shapes[0].measure.vertices,
        "triangles": shapes[0].measure.triangles,
        "densities": shapes[0].measure.densities,
        "points": shapes[1].points,
        "masses": shapes[1].masses,
    });
    std::fs::write(&out, serde_json::to_string(&json).unwrap()).unwrap();
    println!("wrote {out}");
}
