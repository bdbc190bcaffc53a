//! The integration tests of shapespace-cli, one module per file, built as one test binary
//! (`cargo test -p shapespace-cli --test integration [MODULE::]`).

mod cli;
mod shards;
