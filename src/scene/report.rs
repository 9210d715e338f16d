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
        reason: UriError,
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
    Generate { name: String, reason: GenerateError },
}

/// Why the bytes behind a glTF URI could not be read.
#[derive(Debug, thiserror::Error)]
pub enum UriError {
    #[error("a data URI must be base64-encoded (';base64,')")]
    NotBase64,
    #[error("bad base64: {0}")]
    Base64(base64::DecodeError),
    #[error("only data: URIs and relative paths are supported")]
    Scheme,
    #[error("an in-memory scene cannot refer to external files")]
    InMemory,
    #[error("bad percent-escape in URI '{uri}'")]
    PercentEscape { uri: String },
    #[error("URI '{uri}' does not decode to UTF-8")]
    NotUtf8 { uri: String },
    #[error("{} ({error})", path.display())]
    Read {
        path: std::path::PathBuf,
        error: std::io::Error,
    },
    #[error(
        "it names {}, outside the scene's folder {}: a scene reads files only from its own \
         folder and below (--trust-scene lets a scene you trust read any file)",
        target.display(),
        folder.display()
    )]
    Outside {
        target: std::path::PathBuf,
        folder: std::path::PathBuf,
    },
}

/// Why a scene could not be generated.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum GenerateError {
    #[error("--blocks must be in 1..={max}, got {got}")]
    Blocks { max: u32, got: u32 },
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
