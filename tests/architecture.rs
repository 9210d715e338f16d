//! The layering of `src/`, read from the code's own paths: every `crate::…` and `super::…`
//! path outside `#[cfg(test)]` modules is an import of the module it names. The rule
//! (README, "Architecture"):
//!
//! * a module imports only from its own layer or the layers below it ([`LAYERS`], lowest
//!   first);
//! * the top-level modules form no cycle (a stage may use another stage, never both ways);
//! * the files form no cycle, apart from a folder's `mod.rs` and its own children (the parent
//!   re-exports, the children use the parent's types).
//!
//! A failure names both ends of the offending import.
//!
//! GPU kernels pair with their CPU twins by name, as Vello's do ([`twin_of`]): the kernel
//! `shaders/<stage>/<k>.wgsl` is computed by `src/<stage>/<k>.rs` (or `src/<stage>/<k>/`), the
//! definitions every kernel of a stage shares (`shaders/<stage>/common.wgsl`) live in
//! `src/<stage>/mod.rs`, `shaders/<k>.wgsl` pairs with `src/<k>.rs`, each twin names its kernel
//! file, and a stage's kernels are dispatched from its `gpu` module (`src/<stage>/gpu.rs` or
//! `src/<stage>/gpu/mod.rs`).
//!
//! Sizes, for a newcomer's reading: no file of `src/` over [`MAX_FILE_LINES`] lines (its unit
//! tests apart: they live in `<file>/tests.rs`), and no function over [`MAX_FN_LINES`] lines
//! unless a `// Long:` comment directly above it says why it stays whole (a hot loop kept in
//! one piece, a CPU twin that follows its kernel line for line).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers, lowest first, each with its top-level modules.
const LAYERS: &[(&str, &[&str])] = &[
    ("base", &["messages", "input", "random", "gpu"]),
    (
        "stages",
        &[
            "display",
            "scene",
            "tracking",
            "interaction",
            "roi",
            "schedule",
            "trace",
            "filter",
            "output",
        ],
    ),
    ("frame", &["frame", "memory", "cluster"]),
    ("session", &["session"]),
    ("front ends", &["bench", "viewer"]),
    ("command line", &["cli"]),
];

fn layer_of(top: &str) -> Option<usize> {
    LAYERS.iter().position(|(_, mods)| mods.contains(&top))
}

/// Module path of a source file: `src/a/b.rs` and `src/a/b/mod.rs` are `a::b`.
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The code of a file without comments, string contents and `#[cfg(test)]` items.
fn code_of(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            let end = text[i + 2..].find("*/").map_or(b.len(), |e| i + 2 + e + 2);
            i = end;
        } else if b[i] == b'"' {
            // Raw strings are rare in paths' way; plain strings are skipped with escapes.
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else if b[i] == b'\'' && i + 2 < b.len() && (b[i + 2] == b'\'' || b[i + 1] == b'\\') {
            // A char literal ('x' or '\n'): skip it, so that '"' does not open a string.
            let close = text[i + 1..].find('\'').map_or(b.len(), |e| i + 1 + e + 1);
            i = close.max(i + 3);
        } else {
            out.push(b[i] as char);
            i += 1;
        }
    }
    strip_test_items(&out)
}

/// Removes every item that follows `#[cfg(test)]` (a test module or a test-only function):
/// tests may reach anywhere.
fn strip_test_items(code: &str) -> String {
    let mut out = String::new();
    let mut rest = code;
    while let Some(at) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..at]);
        let after = &rest[at..];
        // The item ends at its closing brace (or at `;` for `mod tests;`).
        let mut depth = 0usize;
        let mut end = after.len();
        for (k, c) in after.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = k + 1;
                        break;
                    }
                }
                ';' if depth == 0 => {
                    end = k + 1;
                    break;
                }
                _ => {}
            }
        }
        rest = &after[end..];
    }
    out.push_str(rest);
    out
}

/// Every path a `use` tree names, expanded: `use crate::{a::b, c::{d, e}}` gives
/// `crate::a::b`, `crate::c::d`, `crate::c::e`.
fn expand_use(tree: &str, prefix: &str, out: &mut Vec<String>) {
    let tree = tree.trim();
    if let Some(open) = tree.find('{') {
        let head = tree[..open].trim().trim_end_matches("::");
        let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
        let base = join(prefix, head);
        let mut depth = 0;
        let mut start = 0;
        for (k, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    expand_use(&inner[start..k], &base, out);
                    start = k + 1;
                }
                _ => {}
            }
        }
        expand_use(&inner[start..], &base, out);
    } else if !tree.is_empty() {
        let path = tree.split(" as ").next().unwrap().trim();
        // `use a::{self, b}`: `self` is `a` itself.
        out.push(if path == "self" {
            prefix.to_owned()
        } else {
            join(prefix, path)
        });
    }
}

fn join(a: &str, b: &str) -> String {
    match (a.is_empty(), b.is_empty()) {
        (true, _) => b.to_owned(),
        (_, true) => a.to_owned(),
        _ => format!("{a}::{b}"),
    }
}

/// The paths a file's code names: its `use` trees and every inline `crate::…` / `super::…`.
fn paths_in(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = code;
    // `use` statements (possibly `pub use`, spanning lines).
    while let Some(at) = find_word(rest, "use") {
        let after = &rest[at + 3..];
        let end = after.find(';').unwrap_or(after.len());
        expand_use(&after[..end], "", &mut out);
        rest = &after[end..];
    }
    // Inline paths.
    for start in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(k) = code[from..].find(start) {
            let at = from + k;
            let prev = code[..at].chars().next_back();
            if !prev.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                let len = code[at..]
                    .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                    .unwrap_or(code.len() - at);
                let path = code[at..at + len].trim_end_matches(':');
                // `crate::{…}` is a use tree, read above.
                if path.contains("::") {
                    out.push(path.to_owned());
                }
            }
            from = at + start.len();
        }
    }
    out
}

fn find_word(s: &str, word: &str) -> Option<usize> {
    let mut from = 0;
    while let Some(k) = s[from..].find(word) {
        let at = from + k;
        let before = s[..at].chars().next_back();
        let after = s[at + word.len()..].chars().next();
        let boundary = |c: Option<char>| !c.is_some_and(|c| c.is_alphanumeric() || c == '_');
        if boundary(before) && after.is_some_and(char::is_whitespace) {
            return Some(at);
        }
        from = at + word.len();
    }
    None
}

/// The module a path names, as the longest prefix that is a module of the crate.
fn resolve(
    path: &str,
    here: &[String],
    here_is_mod_rs: bool,
    modules: &BTreeSet<Vec<String>>,
) -> Option<Vec<String>> {
    let mut segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
    let mut base: Vec<String> = match segs.first() {
        Some(&"crate") => {
            segs.remove(0);
            Vec::new()
        }
        Some(&"super") => {
            // `super` of `a::b` (file b.rs) is `a`; of `a::b` (b/mod.rs) also `a`.
            let _ = here_is_mod_rs;
            let mut b = here.to_vec();
            while segs.first() == Some(&"super") {
                segs.remove(0);
                b.pop();
            }
            b
        }
        _ => return None,
    };
    let mut best = None;
    for s in segs {
        base.push(s.to_owned());
        if modules.contains(&base) {
            best = Some(base.clone());
        } else {
            break;
        }
    }
    best
}

struct Graph {
    /// File module path → the modules it imports, with one example path each.
    edges: BTreeMap<Vec<String>, BTreeMap<Vec<String>, String>>,
}

fn graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.retain(|f| {
        let name = f.strip_prefix(&src).unwrap();
        name != Path::new("lib.rs") && name != Path::new("main.rs")
    });
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| module_of(&src, f)).collect();
    let mut edges = BTreeMap::new();
    for f in &files {
        let here = module_of(&src, f);
        let is_mod_rs = f.file_name().is_some_and(|n| n == "mod.rs");
        let code = code_of(&std::fs::read_to_string(f).unwrap());
        let mut out: BTreeMap<Vec<String>, String> = BTreeMap::new();
        for p in paths_in(&code) {
            if let Some(target) = resolve(&p, &here, is_mod_rs, &modules)
                && target != here
            {
                out.entry(target).or_insert(p);
            }
        }
        edges.insert(here, out);
    }
    Graph { edges }
}

fn file_name(m: &[String]) -> String {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let joined = m.join("/");
    if src.join(format!("{joined}/mod.rs")).exists() {
        format!("src/{joined}/mod.rs")
    } else {
        format!("src/{joined}.rs")
    }
}

#[test]
fn every_top_level_module_has_a_layer() {
    let g = graph();
    let tops: BTreeSet<&String> = g.edges.keys().filter_map(|m| m.first()).collect();
    let missing: Vec<&&String> = tops.iter().filter(|t| layer_of(t).is_none()).collect();
    assert!(
        missing.is_empty(),
        "modules without a layer in LAYERS: {missing:?}"
    );
}

#[test]
fn imports_point_down_or_sideways_never_up() {
    let g = graph();
    let mut bad = Vec::new();
    for (from, targets) in &g.edges {
        let Some(lf) = layer_of(&from[0]) else {
            continue;
        };
        for (to, example) in targets {
            let Some(lt) = layer_of(&to[0]) else { continue };
            if lt > lf {
                bad.push(format!(
                    "{} ({}) imports {} ({}) via `{example}`",
                    file_name(from),
                    LAYERS[lf].0,
                    file_name(to),
                    LAYERS[lt].0
                ));
            }
        }
    }
    assert!(bad.is_empty(), "upward imports:\n{}", bad.join("\n"));
}

/// A cycle in `edges`, as the list of nodes around it.
fn find_cycle<N: Ord + Clone>(edges: &BTreeMap<N, BTreeSet<N>>) -> Option<Vec<N>> {
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        Open,
        Done,
    }
    fn visit<N: Ord + Clone>(
        n: &N,
        edges: &BTreeMap<N, BTreeSet<N>>,
        marks: &mut BTreeMap<N, Mark>,
        stack: &mut Vec<N>,
    ) -> Option<Vec<N>> {
        match marks.get(n) {
            Some(Mark::Done) => return None,
            Some(Mark::Open) => {
                let at = stack.iter().position(|s| s == n).unwrap();
                let mut cycle = stack[at..].to_vec();
                cycle.push(n.clone());
                return Some(cycle);
            }
            None => {}
        }
        marks.insert(n.clone(), Mark::Open);
        stack.push(n.clone());
        for m in edges.get(n).into_iter().flatten() {
            if let Some(c) = visit(m, edges, marks, stack) {
                return Some(c);
            }
        }
        stack.pop();
        marks.insert(n.clone(), Mark::Done);
        None
    }
    let mut marks = BTreeMap::new();
    for n in edges.keys() {
        let mut stack = Vec::new();
        if let Some(c) = visit(n, edges, &mut marks, &mut stack) {
            return Some(c);
        }
    }
    None
}

#[test]
fn top_level_modules_form_no_cycle() {
    let g = graph();
    let mut tops: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (from, targets) in &g.edges {
        let set = tops.entry(from[0].clone()).or_default();
        for to in targets.keys() {
            if to[0] != from[0] {
                set.insert(to[0].clone());
            }
        }
    }
    if let Some(cycle) = find_cycle(&tops) {
        let mut why = Vec::new();
        for w in cycle.windows(2) {
            let example = g
                .edges
                .iter()
                .filter(|(f, _)| f[0] == w[0])
                .flat_map(|(f, t)| t.iter().map(move |(to, p)| (f, to, p)))
                .find(|(_, to, _)| to[0] == w[1])
                .map(|(f, to, p)| format!("{} → {} via `{p}`", file_name(f), file_name(to)))
                .unwrap_or_default();
            why.push(example);
        }
        panic!(
            "the top-level modules {} form a cycle:\n{}",
            cycle.join(" → "),
            why.join("\n")
        );
    }
}

#[test]
fn files_form_no_cycle() {
    let g = graph();
    let mut files: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (from, targets) in &g.edges {
        let set = files.entry(from.clone()).or_default();
        for to in targets.keys() {
            // A folder's mod.rs and its own children may use each other.
            let parent_child = (to.len() == from.len() + 1 && to.starts_with(from))
                || (from.len() == to.len() + 1 && from.starts_with(to));
            if !parent_child {
                set.insert(to.clone());
            }
        }
    }
    // Every cycle, one at a time: report it, cut its first edge, look again.
    let mut report = Vec::new();
    while let Some(cycle) = find_cycle(&files) {
        let names: Vec<String> = cycle.iter().map(|m| file_name(m)).collect();
        report.push(format!("files import each other ({}):", names.join(" → ")));
        for w in cycle.windows(2) {
            report.push(format!(
                "  {} → {} via `{}`",
                file_name(&w[0]),
                file_name(&w[1]),
                g.edges[&w[0]][&w[1]]
            ));
        }
        files.get_mut(&cycle[0]).unwrap().remove(&cycle[1]);
    }
    assert!(report.is_empty(), "{}", report.join("\n"));
}

/// The checker itself, on code whose answer is known.
#[test]
fn the_path_reader_expands_use_trees_and_skips_comments_strings_and_tests() {
    let code = code_of(
        r#"
        use crate::{a::b, c::{d, e as f}};
        pub use super::g::H;
        // use crate::commented::Out;
        /// [`crate::doc::Link`]
        fn x() { let s = "crate::in_string"; crate::inline::call(); let c = '"'; }
        #[cfg(test)]
        mod tests { use crate::only_tests; }
        "#,
    );
    let mut p = paths_in(&code);
    p.sort();
    p.dedup();
    assert_eq!(
        p,
        [
            "crate::a::b",
            "crate::c::d",
            "crate::c::e",
            "crate::inline::call",
            "super::g::H"
        ]
    );
    let modules: BTreeSet<Vec<String>> = [vec!["s".to_owned()], vec!["s".into(), "g".into()]]
        .into_iter()
        .collect();
    let here = vec!["s".to_owned(), "h".to_owned()];
    assert_eq!(
        resolve("super::g::H", &here, false, &modules),
        Some(vec!["s".to_owned(), "g".to_owned()])
    );
    assert_eq!(resolve("crate::nowhere", &here, false, &modules), None);
    let mut edges: BTreeMap<u8, BTreeSet<u8>> = BTreeMap::new();
    edges.insert(1, [2].into());
    edges.insert(2, [3].into());
    assert_eq!(find_cycle(&edges), None);
    edges.insert(3, [1].into());
    assert_eq!(find_cycle(&edges), Some(vec![1, 2, 3, 1]));
}

/// The CPU twin of a kernel file (relative to the crate root): `shaders/<stage>/<k>.wgsl` →
/// `src/<stage>/<k>.rs` or `src/<stage>/<k>/mod.rs`; `shaders/<stage>/common.wgsl` →
/// `src/<stage>/mod.rs`; `shaders/<k>.wgsl` → `src/<k>.rs`. The candidates, first preferred.
fn twin_of(kernel: &Path) -> Vec<PathBuf> {
    let rel = kernel.strip_prefix("shaders").unwrap();
    let stem = rel.file_stem().unwrap().to_string_lossy().into_owned();
    match rel.parent().filter(|p| !p.as_os_str().is_empty()) {
        None => vec![Path::new("src").join(format!("{stem}.rs"))],
        Some(stage) if stem == "common" => vec![Path::new("src").join(stage).join("mod.rs")],
        Some(stage) => vec![
            Path::new("src").join(stage).join(format!("{stem}.rs")),
            Path::new("src").join(stage).join(&stem).join("mod.rs"),
        ],
    }
}

fn wgsl_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            wgsl_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            out.push(path);
        }
    }
}

/// The file of a stage's dispatching module `<stage>::gpu`: `src/<stage>/gpu.rs`, or
/// `src/<stage>/gpu/mod.rs` where the module is a folder (its other files do the module's
/// other jobs; the kernels are included by the module's own file).
fn gpu_module_file(root: &Path, stage: &Path) -> PathBuf {
    let file = Path::new("src").join(stage).join("gpu.rs");
    let folder = Path::new("src").join(stage).join("gpu").join("mod.rs");
    if !root.join(&file).is_file() && root.join(&folder).is_file() {
        folder
    } else {
        file
    }
}

/// Why the kernel `rel` (`shaders/<stage>/<k>.wgsl`, relative to `root`) is not dispatched
/// from its stage, if it is not: a stage kernel is included by the file of its stage's `gpu`
/// module ([`gpu_module_file`]), not by another module's and not by a child of `gpu`.
fn dispatch_problem(root: &Path, rel: &Path) -> Option<String> {
    let stage = rel.parent()?.strip_prefix("shaders").ok()?;
    if stage.as_os_str().is_empty() {
        return None;
    }
    let name = rel.file_name()?.to_string_lossy();
    let gpu = gpu_module_file(root, stage);
    let include = format!("shaders/{}/{name}\")", stage.display());
    let dispatch = std::fs::read_to_string(root.join(&gpu)).unwrap_or_default();
    (!dispatch.contains(&include)).then(|| {
        format!(
            "{}: not included by {} (dispatch lives in the stage's gpu module)",
            rel.display(),
            gpu.display()
        )
    })
}

#[test]
fn every_kernel_has_a_cpu_twin_of_its_name_and_is_dispatched_from_its_stage() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut kernels = Vec::new();
    wgsl_files(&root.join("shaders"), &mut kernels);
    assert!(kernels.len() >= 10, "found only {kernels:?}");
    let mut problems = Vec::new();
    for kernel in &kernels {
        let rel = kernel.strip_prefix(root).unwrap().to_path_buf();
        let name = rel.file_name().unwrap().to_string_lossy().into_owned();
        let candidates = twin_of(&rel);
        let Some(twin) = candidates.iter().find(|c| root.join(c).is_file()) else {
            problems.push(format!(
                "{}: no CPU twin (looked for {})",
                rel.display(),
                candidates
                    .iter()
                    .map(|c| c.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            continue;
        };
        let text = std::fs::read_to_string(root.join(twin)).unwrap();
        if !text.contains(&name) {
            problems.push(format!(
                "{}: its twin {} does not name it",
                rel.display(),
                twin.display()
            ));
        }
        problems.extend(dispatch_problem(root, &rel));
    }
    assert!(
        problems.is_empty(),
        "kernels and twins:\n  {}",
        problems.join("\n  ")
    );
}

/// The dispatch rule on made-up trees: a kernel included by `src/<stage>/gpu.rs` or by
/// `src/<stage>/gpu/mod.rs` passes; one included only by a child of `gpu/`, by another
/// module, or by nothing fails naming the file that should include it.
#[test]
fn the_dispatch_rule_takes_the_gpu_module_file_and_nothing_else() {
    let root = std::env::temp_dir().join(format!("raygun-arch-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let write = |rel: &str, text: &str| {
        let p = root.join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    };
    let kernel = Path::new("shaders/trace/path.wgsl");
    let include = r#"include_str!("../../../shaders/trace/path.wgsl")"#;
    assert!(
        dispatch_problem(&root, kernel)
            .unwrap()
            .contains("src/trace/gpu.rs")
    );
    write("src/trace/gpu/mod.rs", "mod run;");
    write("src/trace/gpu/run.rs", include);
    write("src/frame/mod.rs", include);
    let problem = dispatch_problem(&root, kernel).expect("a child of gpu/ does not dispatch");
    assert!(problem.contains("src/trace/gpu/mod.rs"), "{problem}");
    write("src/trace/gpu/mod.rs", include);
    assert_eq!(dispatch_problem(&root, kernel), None);
    std::fs::remove_dir_all(root.join("src/trace/gpu")).unwrap();
    assert!(dispatch_problem(&root, kernel).is_some());
    write("src/trace/gpu.rs", include);
    assert_eq!(dispatch_problem(&root, kernel), None);
    // Kernels of no stage (`shaders/<k>.wgsl`) are anyone's to include.
    assert_eq!(
        dispatch_problem(&root, Path::new("shaders/random.wgsl")),
        None
    );
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn twin_names_follow_the_rule() {
    let t = |k: &str| twin_of(Path::new(k));
    assert_eq!(t("shaders/random.wgsl"), [PathBuf::from("src/random.rs")]);
    assert_eq!(
        t("shaders/filter/common.wgsl"),
        [PathBuf::from("src/filter/mod.rs")]
    );
    assert_eq!(
        t("shaders/roi/ellipse.wgsl"),
        [
            PathBuf::from("src/roi/ellipse.rs"),
            PathBuf::from("src/roi/ellipse/mod.rs")
        ]
    );
}

/// The README's Architecture section shows the layers of [`LAYERS`] and the frame function's
/// steps as they are in `src/frame/steps.rs`.
#[test]
fn the_readme_shows_the_layers_and_the_frame_steps_as_they_are() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    for (layer, modules) in LAYERS {
        let listed = modules
            .iter()
            .map(|m| format!("`{m}`"))
            .collect::<Vec<_>>()
            .join(", ");
        let row = format!("| {layer}");
        let line = readme
            .lines()
            .find(|l| l.starts_with(&row))
            .unwrap_or_else(|| panic!("README: no row for the layer {layer}"));
        assert!(
            line.contains(&format!("| {listed} |")),
            "README's row for {layer} does not list {listed}: {line}"
        );
    }
    let frame = std::fs::read_to_string(root.join("src/frame/steps.rs")).unwrap();
    let body = frame
        .split("fn run_frame(")
        .nth(1)
        .and_then(|rest| rest.split("\n    }\n").next())
        .expect("run_frame in src/frame/steps.rs");
    let steps: Vec<&str> = body.lines().skip(1).map(str::trim).collect();
    assert!(steps.len() >= 4, "{steps:?}");
    for step in steps {
        assert!(
            readme.lines().any(|l| l.trim_start().starts_with(step)),
            "README does not show the frame step `{step}`"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Citations of the design document.
//
// The code cites `docs/DESIGN.md` by section (the file name, then `§N`, a range `§4–5` or a
// list `§6, §12`). Every cited section must exist as a heading `## N.` of that file, and no
// citation may point at a copy outside the repository. Inside the design document itself every
// `§N` is such a citation. Markdown links in README.md and docs/ must name files that exist
// and, into the design document, anchors that its headings give.

/// Where citations are looked for (relative to the repository root): folders walked, and files.
const CITING: &[&str] = &["src", "shaders", "tests", "tools", "docs", "README.md"];

/// The design document, relative to the repository root.
const DESIGN: &str = "docs/DESIGN.md";

/// The file name a citation starts with. Built at run time so that this file's own text holds
/// no citation.
fn design_name() -> String {
    ["DESIGN", ".md"].concat()
}

/// Every text file under `rel` (a folder or a file), with its path relative to `root`; files
/// that are not UTF-8 (images, scenes, captures) are skipped.
fn text_files(root: &Path, rel: &Path, out: &mut Vec<(PathBuf, String)>) {
    let path = root.join(rel);
    if path.is_dir() {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(&path)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        entries.sort();
        for p in entries {
            text_files(root, p.strip_prefix(root).unwrap(), out);
        }
    } else if let Ok(text) = std::fs::read_to_string(&path) {
        out.push((rel.to_owned(), text));
    }
}

fn citing_files() -> Vec<(PathBuf, String)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for rel in CITING {
        text_files(root, Path::new(rel), &mut files);
    }
    files
}

/// The section numbers of the design document's `## N.` headings.
fn design_sections(text: &str) -> BTreeSet<u32> {
    text.lines()
        .filter_map(|l| l.strip_prefix("## "))
        .filter_map(|h| h.split_once('.'))
        .filter_map(|(n, _)| n.parse().ok())
        .collect()
}

/// The leading decimal number of `s` and the rest, or `None` when `s` starts with no digit.
fn leading_number(s: &str) -> Option<(u32, &str)> {
    let end = s.find(|c: char| !c.is_ascii_digit()).unwrap_or(s.len());
    s[..end].parse().ok().map(|n| (n, &s[end..]))
}

/// The sections cited by the text that follows a `§`: `4`, a range `4–5` (en dash or
/// hyphen), then, with `lists`, any further `, §N` or ` and §N` (each a number or a range).
fn sections_after_mark(mut s: &str, lists: bool) -> Vec<u32> {
    let mut cited = Vec::new();
    while let Some((first, rest)) = leading_number(s) {
        let range_end = rest
            .strip_prefix('–')
            .or_else(|| rest.strip_prefix('-'))
            .and_then(leading_number);
        match range_end {
            Some((last, after)) if last >= first => {
                cited.extend(first..=last);
                s = after;
            }
            _ => {
                cited.push(first);
                s = rest;
            }
        }
        match s.strip_prefix(", §").or_else(|| s.strip_prefix(" and §")) {
            Some(next) if lists => s = next,
            _ => break,
        }
    }
    cited
}

/// The sections a line cites: after every mention of the design document (`DESIGN.md §N`,
/// also with the name in backquotes), and — in the design document itself — after every `§`.
fn cited_sections(line: &str, in_design: bool) -> Vec<u32> {
    let mut cited = Vec::new();
    if in_design {
        for (at, _) in line.match_indices('§') {
            cited.extend(sections_after_mark(&line[at + '§'.len_utf8()..], false));
        }
        return cited;
    }
    let name = design_name();
    for (at, _) in line.match_indices(&name) {
        let rest = line[at + name.len()..].trim_start_matches('`').trim_start();
        if let Some(after) = rest.strip_prefix('§') {
            cited.extend(sections_after_mark(after, true));
        }
    }
    cited
}

#[test]
fn the_citation_reader_finds_sections_ranges_and_lists() {
    let d = design_name();
    assert_eq!(cited_sections(&format!("({d} §5's bound)"), false), [5]);
    assert_eq!(cited_sections(&format!("of `{d}` §1, one"), false), [1]);
    assert_eq!(cited_sections(&format!("({d} §4–5)"), false), [4, 5]);
    assert_eq!(
        cited_sections(&format!("({d} §1, §10, §4)"), false),
        [1, 10, 4]
    );
    assert_eq!(
        cited_sections(&format!("{d} §7 and §9; {d} §12"), false),
        [7, 9, 12]
    );
    assert_eq!(
        cited_sections(&format!("{d} §N, and §3"), false),
        Vec::<u32>::new()
    );
    assert_eq!(
        cited_sections("a §3 without the file", false),
        Vec::<u32>::new()
    );
    assert_eq!(cited_sections("see §3 and §16", true), [3, 16]);
    assert_eq!(
        design_sections("# t\n## 1. One\ntext\n## 12. Twelve\n### 3. not a section\n"),
        BTreeSet::from([1, 12])
    );
}

/// Every `DESIGN.md §N` in the repository names a section `## N.` of docs/DESIGN.md.
#[test]
fn every_design_citation_names_a_section_that_exists() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let design = std::fs::read_to_string(root.join(DESIGN))
        .unwrap_or_else(|e| panic!("{DESIGN}: {e} (the code cites it by section)"));
    let sections = design_sections(&design);
    assert!(sections.contains(&1), "{DESIGN} has no `## 1.` heading");
    let mut bad = Vec::new();
    let mut count = 0;
    for (file, text) in citing_files() {
        let in_design = file == Path::new(DESIGN);
        for (i, line) in text.lines().enumerate() {
            for n in cited_sections(line, in_design) {
                count += 1;
                if !sections.contains(&n) {
                    bad.push(format!(
                        "{}:{}: §{n}: {}",
                        file.display(),
                        i + 1,
                        line.trim()
                    ));
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "citations of sections {DESIGN} does not have (its sections: {sections:?}):\n  {}",
        bad.join("\n  ")
    );
    assert!(
        count > 100,
        "only {count} citations found: is the reader broken?"
    );
}

/// No citation or link points at a design document outside the repository, and every relative
/// Markdown link of README.md and docs/ names a file that exists — into the design document with
/// an anchor that one of its headings gives.
#[test]
fn citations_and_links_stay_inside_the_repository() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let name = design_name();
    // Phrases that send a reader out of the repository, built so this file holds none of them.
    let outside = [
        ["shared", " notes"].concat(),
        ["..", "/shared"].concat(),
        ["project's", " shared"].concat(),
        ["/work", "/"].concat(),
    ];
    let design = std::fs::read_to_string(root.join(DESIGN)).unwrap();
    let anchors: BTreeSet<String> = design
        .lines()
        .filter_map(|l| l.strip_prefix("## "))
        .map(slug)
        .collect();
    let mut bad = Vec::new();
    for (file, text) in citing_files() {
        let markdown = file.extension().is_some_and(|e| e == "md");
        let linking = markdown && (file.starts_with("docs") || file == Path::new("README.md"));
        for (i, line) in text.lines().enumerate() {
            let at = format!("{}:{}", file.display(), i + 1);
            for phrase in &outside {
                if line.contains(phrase.as_str()) {
                    bad.push(format!("{at}: says {phrase:?}: {}", line.trim()));
                }
            }
            if !linking {
                continue;
            }
            for target in link_targets(line) {
                if target.contains("://")
                    || target.starts_with('#')
                    || target.starts_with("mailto:")
                {
                    continue;
                }
                let (path, anchor) = target.split_once('#').unwrap_or((target, ""));
                let resolved = root.join(file.parent().unwrap()).join(path);
                if !resolved.exists() {
                    bad.push(format!("{at}: links {target:?}, which does not exist"));
                } else if path.ends_with(&name) {
                    let canonical = resolved.canonicalize().unwrap();
                    if canonical != root.join(DESIGN).canonicalize().unwrap() {
                        bad.push(format!("{at}: links a {name} other than {DESIGN}"));
                    } else if !anchor.is_empty() && !anchors.contains(anchor) {
                        bad.push(format!("{at}: {DESIGN} has no heading for #{anchor}"));
                    }
                }
            }
        }
    }
    assert!(
        bad.is_empty(),
        "links out of place:\n  {}",
        bad.join("\n  ")
    );
}

/// The targets of the Markdown links `[text](target)` on a line.
fn link_targets(line: &str) -> Vec<&str> {
    line.match_indices("](")
        .filter_map(|(at, _)| {
            let rest = &line[at + 2..];
            rest.find(')').map(|end| rest[..end].trim())
        })
        .filter(|t| !t.is_empty() && !t.contains(' '))
        .collect()
}

/// The anchor GitHub gives a heading: lower case, spaces as hyphens, other punctuation dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            '-' | '_' => Some(c),
            c if c.is_alphanumeric() => Some(c.to_lowercase().next().unwrap_or(c)),
            _ => None,
        })
        .collect()
}

#[test]
fn heading_anchors_are_githubs() {
    assert_eq!(slug("10. Tracking ingest"), "10-tracking-ingest");
    assert_eq!(slug("14. Scenes and glTF"), "14-scenes-and-gltf");
    assert_eq!(
        slug("9. The paper's setup and numbers"),
        "9-the-papers-setup-and-numbers"
    );
}

// ---------------------------------------------------------------------------------------------
// Sizes: no source file over `MAX_FILE_LINES` lines (tests apart), no function over
// `MAX_FN_LINES` lines without a stated reason.

/// The most lines a file of `src/` may have, not counting a `#[cfg(test)]` module written in it
/// (the unit tests of a large file go to `<file>/tests.rs`, which is exempt).
const MAX_FILE_LINES: usize = 1000;

/// The most lines a function may span, from its `fn` to its closing brace, unless a `// Long:`
/// comment directly above it (among its doc comments and attributes) says why it is longer.
const MAX_FN_LINES: usize = 150;

/// `text` with comments and the insides of string and char literals blanked (newlines kept, so
/// that lines still count), leaving braces and keywords that are code.
fn blank_non_code(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let at = |j: usize| c.get(j).copied().unwrap_or('\0');
    let blank = |ch: char| if ch == '\n' { '\n' } else { ' ' };
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < c.len() {
        let after_ident = i > 0 && (c[i - 1].is_alphanumeric() || c[i - 1] == '_');
        // A raw string's prefix length (`r`, `br`) and its number of `#`s.
        let raw = (!after_ident)
            .then(|| match (at(i), at(i + 1)) {
                ('r', _) => Some(1),
                ('b', 'r') => Some(2),
                _ => None,
            })
            .flatten()
            .and_then(|p| {
                let hashes = (i + p..).take_while(|&j| at(j) == '#').count();
                (at(i + p + hashes) == '"').then_some((p, hashes))
            });
        if at(i) == '/' && at(i + 1) == '/' {
            while i < c.len() && c[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if at(i) == '/' && at(i + 1) == '*' {
            // Block comments nest.
            let mut depth = 0;
            while i < c.len() {
                if at(i) == '/' && at(i + 1) == '*' {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if at(i) == '*' && at(i + 1) == '/' {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(blank(c[i]));
                    i += 1;
                }
            }
        } else if let Some((prefix, hashes)) = raw {
            let open = prefix + hashes + 1;
            out.extend(&c[i..i + open]);
            i += open;
            while i < c.len() && !(c[i] == '"' && (1..=hashes).all(|k| at(i + k) == '#')) {
                out.push(blank(c[i]));
                i += 1;
            }
            let close = (hashes + 1).min(c.len() - i);
            out.extend(&c[i..i + close]);
            i += close;
        } else if at(i) == '"' {
            out.push('"');
            i += 1;
            while i < c.len() && c[i] != '"' {
                let len = if c[i] == '\\' { 2 } else { 1 };
                for &ch in &c[i..(i + len).min(c.len())] {
                    out.push(blank(ch));
                }
                i += len;
            }
            if i < c.len() {
                out.push('"');
                i += 1;
            }
        } else if at(i) == '\'' && (at(i + 1) == '\\' || at(i + 2) == '\'') {
            // A char literal ('x', '\n', '\u{7f}'); a lifetime ('a) has no closing quote.
            out.push('\'');
            i += 1;
            while i < c.len() && c[i] != '\'' {
                let len = if c[i] == '\\' { 2 } else { 1 };
                for &ch in &c[i..(i + len).min(c.len())] {
                    out.push(blank(ch));
                }
                i += len;
            }
            if i < c.len() {
                out.push('\'');
                i += 1;
            }
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

/// The index of the `}` that closes the `{` at `open` in blanked code (the end where none does).
fn closing_brace(code: &[u8], open: usize) -> usize {
    let mut depth = 0usize;
    for (k, &b) in code.iter().enumerate().skip(open) {
        match b {
            b'{' => depth += 1,
            b'}' => {
                depth -= 1;
                if depth == 0 {
                    return k;
                }
            }
            _ => {}
        }
    }
    code.len()
}

/// The 1-based line of byte `at`.
fn line_at(code: &[u8], at: usize) -> usize {
    code[..at].iter().filter(|&&b| b == b'\n').count() + 1
}

fn is_ident(b: u8) -> bool {
    b.is_ascii_alphanumeric() || b == b'_'
}

/// The lines of a file, not counting those of `#[cfg(test)]` modules written inline.
fn counted_lines(text: &str) -> usize {
    let code = blank_non_code(text);
    let b = code.as_bytes();
    let mut test_lines = 0;
    let mut from = 0;
    while let Some(k) = code[from..].find("#[cfg(test)]") {
        let at = from + k;
        from = at + "#[cfg(test)]".len();
        let rest = code[from..].trim_start();
        let item = code.len() - rest.len();
        let is_mod = rest.starts_with("mod ") || rest.starts_with("pub mod ");
        let open = code[item..].find(['{', ';']).map(|o| item + o);
        if let Some(open) = open.filter(|&o| is_mod && b[o] == b'{') {
            let close = closing_brace(b, open);
            test_lines += line_at(b, close) - line_at(b, at) + 1;
            from = close;
        }
    }
    text.lines().count() - test_lines
}

/// A function with a body: its name, the line of its `fn`, the lines it spans (from there to
/// its closing brace), and whether a `// Long:` comment stands directly above it.
#[derive(Debug, PartialEq)]
struct Function {
    name: String,
    line: usize,
    lines: usize,
    reason: bool,
}

/// Every function with a body in `text` (methods and nested functions included; declarations
/// without a body, `fn(…)` pointer types and macros' `fn $name` skipped).
fn functions(text: &str) -> Vec<Function> {
    let code = blank_non_code(text);
    let b = code.as_bytes();
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(k) = code[from..].find("fn") {
        let at = from + k;
        from = at + 2;
        let keyword = !(at > 0 && is_ident(b[at - 1])) && b.get(at + 2) == Some(&b' ');
        let name_at = at + 3;
        let name_len = b[name_at.min(b.len())..]
            .iter()
            .take_while(|&&c| is_ident(c))
            .count();
        if !keyword || name_len == 0 {
            continue;
        }
        // The body opens at the first `{` outside brackets; a `;` there first means none.
        let mut depth = 0i32;
        let mut open = None;
        for (k, &c) in b.iter().enumerate().skip(name_at + name_len) {
            match c {
                b'(' | b'[' => depth += 1,
                b')' | b']' => depth -= 1,
                b'{' if depth == 0 => {
                    open = Some(k);
                    break;
                }
                b';' if depth == 0 => break,
                _ => {}
            }
        }
        let Some(open) = open else { continue };
        let line = line_at(b, at);
        out.push(Function {
            name: code[name_at..name_at + name_len].to_owned(),
            line,
            lines: line_at(b, closing_brace(b, open)) - line + 1,
            reason: reason_above(&lines, line - 1),
        });
    }
    out
}

/// Whether the comments, doc comments and attributes directly above line `sig` (0-based) hold
/// a `// Long:` comment.
fn reason_above(lines: &[&str], sig: usize) -> bool {
    let mut in_attribute = false;
    for l in lines[..sig].iter().rev().map(|l| l.trim()) {
        if l.starts_with("// Long:") {
            return true;
        }
        if in_attribute {
            // Inside an attribute spread over lines, up to its `#[`.
            in_attribute = !l.starts_with("#[");
        } else if l.ends_with(']') && !l.starts_with("#[") && !l.starts_with("//") {
            in_attribute = true;
        } else if !(l.starts_with("//") || l.starts_with("#[")) {
            return false;
        }
    }
    false
}

#[test]
fn source_files_stay_short_and_functions_long_only_for_a_stated_reason() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    let (mut long_files, mut long_fns) = (Vec::new(), Vec::new());
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let name = f
            .strip_prefix(Path::new(env!("CARGO_MANIFEST_DIR")))
            .unwrap();
        let n = counted_lines(&text);
        if n > MAX_FILE_LINES && f.file_name().is_none_or(|n| n != "tests.rs") {
            long_files.push(format!("{}: {n} lines", name.display()));
        }
        for func in functions(&text) {
            if func.lines > MAX_FN_LINES && !func.reason {
                long_fns.push(format!(
                    "{}:{}: fn {}: {} lines",
                    name.display(),
                    func.line,
                    func.name,
                    func.lines
                ));
            }
        }
    }
    let mut report = Vec::new();
    if !long_files.is_empty() {
        report.push(format!(
            "files over {MAX_FILE_LINES} lines (apart from inline #[cfg(test)] modules: move \
             those to <file>/tests.rs, or split the file by job):\n{}",
            long_files.join("\n")
        ));
    }
    if !long_fns.is_empty() {
        report.push(format!(
            "functions over {MAX_FN_LINES} lines without a `// Long:` reason directly above \
             them (split them, or say why not):\n{}",
            long_fns.join("\n")
        ));
    }
    assert!(report.is_empty(), "{}", report.join("\n"));
}

/// The size scanner itself, on code whose answer is known.
#[test]
fn the_size_scanner_measures_functions_and_skips_literals_comments_and_tests() {
    let body = |n: usize| "    let x = 1;\n".repeat(n);
    // Braces in strings, raw strings, chars, comments; a lifetime; a declaration without a
    // body; a function pointer type.
    let tricky = "fn tricky<'a>(s: &'a str, f: fn(u32) -> u32) -> [u8; 2] {\n    \
                  let _ = (\"{\", r#\"}\"#, '{', '}', '\\'', b'{');\n    \
                  // }\n    /* { /* } */ { */\n    [0; 2]\n}\n";
    let text = format!(
        "trait T {{\n    fn declared(&self);\n}}\n\
         /// Docs.\n#[inline]\nfn short() {{\n{}}}\n\
         fn long() {{\n{}}}\n\
         /// Docs.\n// Long: a reason.\n#[allow(\n    dead_code\n)]\nfn excused() {{\n{}}}\n\
         {tricky}\
         #[cfg(test)]\nmod tests {{\n    fn in_tests() {{\n{}    }}\n}}\n",
        body(148),
        body(149),
        body(300),
        body(10),
    );
    let found = functions(&text);
    let summary: Vec<(&str, usize, bool)> = found
        .iter()
        .map(|f| (f.name.as_str(), f.lines, f.reason))
        .collect();
    assert_eq!(
        summary,
        [
            ("short", 150, false),
            ("long", 151, false),
            ("excused", 302, true),
            ("tricky", 6, false),
            ("in_tests", 12, false),
        ]
    );
    assert_eq!(found[0].line, 6);
    // The inline test module's 15 lines are not counted.
    assert_eq!(counted_lines(&text), text.lines().count() - 15);
    assert_eq!(counted_lines("#[cfg(test)]\nmod tests;\nfn a() {}\n"), 3);
}

/// The 1-based lines of `text` where a `Result<…, String>` type starts: an error that is a bare
/// string, which callers can only print or search. Its generic arguments are read across
/// lines, with whitespace and comments ignored; `io::Result<String>` (one argument, the string
/// is the value) is fine.
fn string_error_results(text: &str) -> Vec<usize> {
    let code = blank_non_code(text);
    let b = code.as_bytes();
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(k) = code[from..].find("Result") {
        let at = from + k;
        from = at + "Result".len();
        if (at > 0 && is_ident(b[at - 1])) || b.get(from).is_some_and(|&c| is_ident(c)) {
            continue;
        }
        // The arguments, whitespace removed, split at the commas between them (a turbofish's
        // `::` is allowed before the `<`).
        let rest: Vec<u8> = b[from..]
            .iter()
            .copied()
            .filter(|c| !c.is_ascii_whitespace())
            .collect();
        let rest = rest.strip_prefix(b"::").unwrap_or(&rest);
        if rest.first() != Some(&b'<') {
            continue;
        }
        let (mut angle, mut brackets) = (0i32, 0i32);
        let mut args = vec![String::new()];
        for (k, &c) in rest.iter().enumerate() {
            match c {
                b'<' => angle += 1,
                b'>' if k > 0 && rest[k - 1] == b'-' => {}
                b'>' => angle -= 1,
                b'(' | b'[' | b'{' => brackets += 1,
                b')' | b']' | b'}' => brackets -= 1,
                b',' if angle == 1 && brackets == 0 => {
                    args.push(String::new());
                    continue;
                }
                b';' => break,
                _ => {}
            }
            if angle == 0 {
                break;
            }
            if !(k == 0 && c == b'<') {
                args.last_mut().unwrap().push(c as char);
            }
        }
        args.retain(|a| !a.is_empty());
        let string = |a: &str| a == "String" || a.ends_with("::String");
        if args.len() == 2 && string(&args[1]) {
            out.push(line_at(b, at));
        }
    }
    out
}

/// Errors are typed (an enum or struct per module, `thiserror`), never `Result<_, String>`:
/// a caller can match a typed error, and its message text stays in one place.
#[test]
fn errors_are_typed_not_strings() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    rust_files(&root.join("src"), &mut files);
    files.sort();
    let mut found = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        for line in string_error_results(&text) {
            let name = f.strip_prefix(root).unwrap().display().to_string();
            found.push(format!("{name}:{line}"));
        }
    }
    assert!(
        found.is_empty(),
        "Result<_, String> (give the error a type, e.g. a thiserror enum, with the same \
         messages):\n{}",
        found.join("\n")
    );
}

/// The string-error scanner itself, on code whose answer is known.
#[test]
fn the_string_error_scanner_reads_signatures_across_lines_and_skips_comments() {
    let text = "fn a() -> Result<u32, String> {}\n\
                fn b(\n    x: u8,\n) -> Result<\n    Vec<(u8, u16)>,\n    String,\n> {}\n\
                fn c() -> io::Result<String> {}\n\
                fn d() -> Result<String, Error> {}\n\
                // fn e() -> Result<(), String>\n\
                fn f() -> \"Result<(), String>\" {}\n\
                fn g(h: impl Fn(u8) -> u8) -> std::result::Result<HashMap<u8, u8>, std::string::String> {}\n\
                fn i() -> MyResult<u8, String> {}\n\
                let j = x.parse::<u8>().map_err(|e| e.to_string())?;\n\
                let k = Result::<(), String>::Ok(());\n\
                fn l() -> Result<u8, Box<dyn Fn() -> String>> {}\n";
    assert_eq!(string_error_results(text), [1, 4, 12, 15]);
}
