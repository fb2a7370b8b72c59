//! What a path does at each vertex, and the two engines that trace paths.
//!
//! - [`sampler`]: the random numbers of every path;
//! - [`reference`](mod@reference): the scalar recursive reference tracer (the oracle);
//! - [`wavefront`]: the SIMD wavefront engine (the default).

pub mod reference;
pub mod sampler;
pub mod wavefront;
