//! Scenes: loading glTF files and their features, the Khronos samples, KTX2 textures,
//! environments, and `raygun scene …`.

mod gltf_features;
mod gltf_samples;
mod scene_cli;
mod scene_environment;
mod scene_ktx2;
mod scene_loading;

// The helpers of tests/support/ that the files above use, each compiled once here.
#[path = "../support/gltf_scenes.rs"]
mod gltf_scenes;
#[path = "../support/render.rs"]
mod render;
#[path = "../support/cli.rs"]
mod support;
