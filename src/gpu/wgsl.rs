//! Checks of the WGSL sources without a GPU: parse and validate with naga (what wgpu does at
//! pipeline creation), and the byte size of a struct shared with Rust (a mismatch would scramble
//! the buffers silently). Used by every kernel's unit tests.

use wgpu::naga;

/// Parses and validates `source`; panics with naga's diagnostic, naming `name`, if it fails.
/// Returns the module for further checks.
pub fn validated(name: &str, source: &str) -> naga::Module {
    let module = naga::front::wgsl::parse_str(source).unwrap_or_else(|e| {
        panic!("{name} does not parse: {}", e.emit_to_string(source));
    });
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name} does not validate: {}", e.emit_to_string(source)));
    module
}

/// The size in bytes of the struct `name` declared in `module`; panics when there is none.
#[must_use]
pub fn struct_size(module: &naga::Module, name: &str) -> usize {
    let (_, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name} in the module"));
    ty.inner.size(module.to_ctx()) as usize
}
