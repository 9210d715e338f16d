//! The wgpu context: adapter choice and the CPU fallback.
