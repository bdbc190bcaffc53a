//! One module per subcommand: its clap `Args` struct and a `run` that calls one library function.

pub mod conformal;
pub mod demo;
pub mod distances;
pub mod info;
pub mod markers;
pub mod mds;
pub mod ot;
pub mod param;
pub mod prepare;
pub mod register;
