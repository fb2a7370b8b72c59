//! Running renders: sessions in sample passes, shards and merges.

pub mod merge;
pub mod session;
pub mod shard;
