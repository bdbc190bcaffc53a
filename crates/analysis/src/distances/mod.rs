//! Conformal Wasserstein distances and the runs that compute them: one shape prepared and one
//! pair on the disk ([`distance`]) or on the sphere ([`sphere_distance`], with the rotation search
//! of [`rotation`]), the invariance search ([`invariance`]), and the pairwise pipeline
//! ([`pipeline`]: markers, caches, resume, shards, partial files). The `distances` command.

pub mod distance;
pub mod inputs;
pub mod invariance;
pub mod merge;
pub mod pipeline;
pub mod report_path;
pub mod resume;
pub mod rotation;
pub mod run_folder;
pub mod run_report;
pub mod run_settings;
pub mod shape_cache;
pub mod shard;
pub mod shared_markers;
pub mod sphere_distance;
