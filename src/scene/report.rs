//! What a glTF load reports: the error that stops it ([`SceneError`]) and what it found besides
//! the triangles ([`Report`]: unsupported features, repairs, notes), shared by the scene walk
//! (`load.rs`) and the resource resolution (`resources.rs`).

use std::collections::HashSet;

/// A scene that cannot be loaded. Every message names the file and the element at fault.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{file}: cannot read the file")]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: not a glTF 2.0 file: {reason}")]
    Parse { file: String, reason: String },
    #[error("{file}: invalid glTF: {problems}")]
    Invalid { file: String, problems: String },
    #[error("{file}: requires extension {extension}, which raygun does not implement")]
    RequiredExtension { file: String, extension: String },
    #[error("{file}: {element}: cannot read '{uri}': {reason}")]
    Resource {
        file: String,
        element: String,
        uri: String,
        reason: crate::scene::resources::UriError,
    },
    #[error("{file}: {element}: {problem}")]
    Element {
        file: String,
        element: String,
        problem: String,
    },
    #[error("unknown built-in scene '{name}' (built-ins: {known})")]
    UnknownBuiltin { name: String, known: String },
    #[error("cannot generate built-in scene '{name}': {reason}")]
    Generate {
        name: String,
        reason: crate::scene::generate::GenerateError,
    },
}

/// `mesh 'Tower'` or `mesh 3`.
pub(super) fn label(kind: &str, name: Option<&str>, index: usize) -> String {
    match name {
        Some(n) => format!("{kind} '{n}'"),
        None => format!("{kind} {index}"),
    }
}

/// What one load found, besides the triangles.
#[derive(Default)]
pub(super) struct Report {
    pub(super) unsupported: Vec<String>,
    seen: HashSet<String>,
    pub(super) warnings: Vec<String>,
    pub(super) notes: Vec<String>,
}

impl Report {
    pub(super) fn unsupported(&mut self, what: String) {
        if self.seen.insert(what.clone()) {
            self.unsupported.push(what);
        }
    }

    pub(super) fn warn(&mut self, what: String) {
        if self.seen.insert(what.clone()) {
            self.warnings.push(what);
        }
    }

    pub(super) fn note(&mut self, what: String) {
        if self.seen.insert(what.clone()) {
            self.notes.push(what);
        }
    }
}
