//! `shapespace`: the command-line front end. Parsing and dispatch only; the work lives in the
//! library crates. Exit codes: 0 ok, 1 some input failed or did not converge, 2 usage or input
//! error. Errors print as `shapespace: {err:#}` on stderr.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cmd;

#[derive(Parser)]
#[command(
    name = "shapespace",
    version,
    about = "Shape analysis with conformal geometry and optimal mass transport"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The main job on the bundled faces: distances, MDS, statistics and plots into out/demo.
    Demo(cmd::demo::DemoArgs),
    /// Conformal Wasserstein distances between disk surfaces: distances.csv, pairs.csv, report.json.
    Distances(cmd::distances::DistancesArgs),
    /// Conformal map of a disk onto the unit disk (OBJ with vt) or of a closed genus-0 mesh onto the unit sphere (positions on S²); factors CSV, report JSON.
    Conformal(cmd::conformal::ConformalArgs),
    /// Assemble the folders of `distances --shard K/N` runs into one run's distances.csv, pairs.csv, report.json.
    Merge(cmd::distances::MergeArgs),
    /// Print mesh statistics (V, F, components, boundary loops, χ, genus, manifoldness, class).
    Info(cmd::info::InfoArgs),
    /// Classical MDS of a distance matrix: coordinates, eigenvalues, plots, 1-NN and silhouette statistics.
    Mds(cmd::mds::MdsArgs),
    /// Semi-discrete optimal transport from a source density to weighted points (damped Newton).
    Ot(cmd::ot::OtArgs),
    /// Area-preserving parameterization onto the disk or square by optimal mass transport (OBJ with vt, report, plots).
    Param(cmd::param::ParamArgs),
    /// Make a disk-topology mesh: drop unreferenced vertices and smaller components, orient, cut a disk out of a closed surface, fill all holes but the longest, split edges between boundary vertices that cut the interior apart.
    Prepare(cmd::prepare::PrepareArgs),
    /// Register a source disk surface onto a target through disk maps and a landmark-constrained harmonic map (correspondence CSV, metrics, histograms).
    Register(cmd::register::RegisterArgs),
    /// Registration benchmark over class folders of poses: all ordered pairs, OMT vs conformal (results.csv, histograms).
    RegisterBench(cmd::register::RegisterBenchArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Conformal(args) => cmd::conformal::run(args),
        Command::Demo(args) => cmd::demo::run(args),
        Command::Distances(args) => cmd::distances::run(args),
        Command::Info(args) => cmd::info::run(args),
        Command::Merge(args) => cmd::distances::run_merge(args),
        Command::Mds(args) => cmd::mds::run(args),
        Command::Ot(args) => cmd::ot::run(args),
        Command::Param(args) => cmd::param::run(args),
        Command::Prepare(args) => cmd::prepare::run(args),
        Command::Register(args) => cmd::register::run(args),
        Command::RegisterBench(args) => cmd::register::run_bench(args),
    };
    match result {
        Ok(code) => code,
        Err(err) => {
            eprintln!("shapespace: {err:#}");
            ExitCode::from(2)
        }
    }
}
