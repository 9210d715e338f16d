//! Checks of the WGSL sources without a GPU: parse and validate with naga (what wgpu does at
//! pipeline creation), and the layout of a struct shared with Rust — its size and every field's
//! offset, from naga's layouter (a mismatch would scramble the buffers silently). Used by every
//! kernel's unit tests.

use wgpu::naga;

/// Parses and validates `source`; panics with naga's diagnostic, naming `name`, if it fails.
/// Returns the module for further checks.
pub fn validated(name: &str, source: &str) -> naga::Module {
    validated_with(name, source, false)
}

/// [`validated`], allowing subgroup operations in compute shaders where `subgroups` (what a
/// device with `wgpu::Features::SUBGROUP` accepts); without it they fail validation.
pub fn validated_with(name: &str, source: &str, subgroups: bool) -> naga::Module {
    use naga::valid::{Capabilities, ShaderStages, SubgroupOperationSet, Validator};
    let module = naga::front::wgsl::parse_str(source).unwrap_or_else(|e| {
        panic!("{name} does not parse: {}", e.emit_to_string(source));
    });
    let mut validator = Validator::new(
        naga::valid::ValidationFlags::all(),
        if subgroups {
            Capabilities::SUBGROUP
        } else {
            Capabilities::empty()
        },
    );
    if subgroups {
        validator
            .subgroup_stages(ShaderStages::COMPUTE)
            .subgroup_operations(SubgroupOperationSet::all());
    }
    validator
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name} does not validate: {}", e.emit_to_string(source)));
    module
}

/// The compute entry point `entry` of `source` as a device compiles its pipeline:
/// [`validated_with`], then every WGSL `override` set — to its value in `constants` (what
/// `wgpu::PipelineCompilationOptions::constants` passes), else to its default — with naga's
/// own pass, the module cut down to what `entry` reaches, and validated again. Panics with
/// naga's diagnostic, naming `name`, if any step fails.
pub fn specialised(
    name: &str,
    source: &str,
    subgroups: bool,
    entry: &str,
    constants: &[(&str, f64)],
) -> naga::Module {
    let module = validated_with(name, source, subgroups);
    let mut validator = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    );
    let info = validator
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name} does not validate: {}", e.emit_to_string(source)));
    let mut values = naga::back::PipelineConstants::default();
    for &(k, v) in constants {
        values.insert(k.to_string(), v);
    }
    let stage = Some((naga::ShaderStage::Compute, entry));
    match naga::back::pipeline_constants::process_overrides(&module, &info, stage, &values) {
        Ok((m, _)) => m.into_owned(),
        Err(e) => panic!("{name}, entry point {entry}: its overrides cannot be set: {e}"),
    }
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

/// The value of the scalar constant `name` declared in `module` (WGSL's `const`, folded by
/// naga's constant evaluator); panics when there is none or it is not a literal.
#[must_use]
pub fn const_literal(module: &naga::Module, name: &str) -> naga::Literal {
    let (_, c) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no constant {name} in the module"));
    match module.global_expressions[c.init] {
        naga::Expression::Literal(l) => l,
        ref other => panic!("constant {name} is not a literal: {other:?}"),
    }
}

/// The members of the struct `name` in `module`: (name, byte offset), in declaration order, with
/// the offsets naga's layouter gave them (WGSL's alignment rules).
#[must_use]
pub fn struct_members(module: &naga::Module, name: &str) -> Vec<(String, u32)> {
    let (_, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name} in the module"));
    match &ty.inner {
        naga::TypeInner::Struct { members, .. } => members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
            .collect(),
        other => panic!("{name} is not a struct: {other:?}"),
    }
}

/// A Rust struct's layout: its name, size and (field, offset) in declaration order, as
/// [`rust_layout!`](crate::rust_layout) gathers it.
#[derive(Debug)]
pub struct RustLayout {
    pub name: &'static str,
    pub size: usize,
    pub fields: Vec<(&'static str, usize)>,
}

/// The [`RustLayout`] of `Type` with the listed fields (all of them, in declaration order).
#[macro_export]
macro_rules! rust_layout {
    ($ty:ty; $($field:ident),+ $(,)?) => {
        $crate::gpu::wgsl::RustLayout {
            name: stringify!($ty),
            size: ::std::mem::size_of::<$ty>(),
            fields: vec![$((stringify!($field), ::std::mem::offset_of!($ty, $field))),+],
        }
    };
}

/// Panics, naming both sides, unless the WGSL struct `wgsl` in `module` and its Rust twin have
/// the same size and the same named fields at the same offsets. Fields whose names start with
/// `_` are padding (WGSL spells `[u32; 3]` as three scalars): they are not paired, the sizes
/// and the other fields' offsets cover them.
pub fn assert_same_layout(module: &naga::Module, wgsl: &str, rust: &RustLayout) {
    let size = struct_size(module, wgsl);
    let members = struct_members(module, wgsl);
    let mut problems = Vec::new();
    if size != rust.size {
        problems.push(format!("size {size} in WGSL, {} in Rust", rust.size));
    }
    let named_wgsl: Vec<&(String, u32)> = members
        .iter()
        .filter(|(n, _)| !n.starts_with('_'))
        .collect();
    for (name, off) in &named_wgsl {
        match rust.fields.iter().find(|(r, _)| r == name) {
            Some((_, roff)) if *roff == *off as usize => {}
            Some((_, roff)) => {
                problems.push(format!("{name} at byte {off} in WGSL, {roff} in Rust"));
            }
            None => problems.push(format!("{name} (byte {off}) is not in Rust")),
        }
    }
    for (name, off) in rust.fields.iter().filter(|(n, _)| !n.starts_with('_')) {
        if !named_wgsl.iter().any(|(w, _)| w == name) {
            problems.push(format!("{name} (byte {off}) is not in WGSL"));
        }
    }
    assert!(
        problems.is_empty(),
        "WGSL struct {wgsl} and Rust {} differ: {}",
        rust.name,
        problems.join("; ")
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    const SRC: &str = "struct S { a: vec2<u32>, b: f32, c: u32, d: vec3<f32>, _pad0: u32 }
        @group(0) @binding(0) var<uniform> s: S;";

    #[test]
    fn members_carry_the_layouters_offsets() {
        let m = validated("test", SRC);
        let names = |v: Vec<(String, u32)>| {
            v.into_iter()
                .map(|(n, o)| format!("{n}@{o}"))
                .collect::<Vec<_>>()
        };
        assert_eq!(
            names(struct_members(&m, "S")),
            ["a@0", "b@8", "c@12", "d@16", "_pad0@28"]
        );
    }

    /// The twin passes with padding spelt differently; a field at another offset, a missing
    /// field, a renamed field or another size is caught.
    #[test]
    fn layouts_are_compared_field_by_field() {
        #[repr(C)]
        struct Good {
            a: [u32; 2],
            b: f32,
            c: u32,
            d: [f32; 3],
            _pad: [u32; 1],
        }
        #[repr(C)]
        struct Swapped {
            a: [u32; 2],
            c: u32,
            b: f32,
            d: [f32; 3],
            _pad: u32,
        }
        #[repr(C)]
        struct Missing {
            a: [u32; 2],
            b: f32,
            _c: u32,
            d: [f32; 3],
            _pad: u32,
        }
        #[repr(C)]
        struct Renamed {
            a: [u32; 2],
            b: f32,
            c: u32,
            e: [f32; 3],
            _pad: u32,
        }
        #[repr(C)]
        struct Short {
            a: [u32; 2],
            b: f32,
            c: u32,
            d: [f32; 3],
        }
        let m = validated("test", SRC);
        assert_same_layout(&m, "S", &crate::rust_layout!(Good; a, b, c, d, _pad));
        for bad in [
            crate::rust_layout!(Swapped; a, c, b, d, _pad),
            crate::rust_layout!(Missing; a, b, _c, d, _pad),
            crate::rust_layout!(Renamed; a, b, c, e, _pad),
            crate::rust_layout!(Short; a, b, c, d),
        ] {
            let name = bad.name;
            let caught = std::panic::catch_unwind(|| assert_same_layout(&m, "S", &bad));
            assert!(caught.is_err(), "{name} passed");
        }
    }
}
