//! Running renders: sessions in sample passes, shards and merges.

pub mod bench;
pub mod converge;
pub mod merge;
pub mod plot;
pub mod session;
pub mod shard;
pub mod views;
pub mod views_cameras;
