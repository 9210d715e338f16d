//! The start-up check: before any work every rank sends rank 0 what it is about to do — its
//! binary, the display model, the tile map, the scene, the settings — or why it could not get
//! that far; rank 0 compares every rank's record with its own and answers with one verdict, so
//! a mismatch stops every rank before the first frame, naming the rank and what differs.

use std::sync::{Arc, OnceLock};

use super::{Cluster, ClusterError};

/// A 64-bit content hash (not cryptographic: it tells builds and files apart, it does not
/// defend against anyone). Words of 8 bytes, multiply-xorshift mixing, the length folded in.
#[must_use]
pub fn content_hash(bytes: &[u8]) -> u64 {
    const K: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut h = 0x243f_6a88_85a3_08d3u64 ^ (bytes.len() as u64).wrapping_mul(K);
    let mut chunks = bytes.chunks_exact(8);
    for c in &mut chunks {
        let w = u64::from_le_bytes(c.try_into().expect("8 bytes"));
        h = (h ^ w).wrapping_mul(K);
        h ^= h >> 29;
    }
    let mut tail = [0u8; 8];
    tail[..chunks.remainder().len()].copy_from_slice(chunks.remainder());
    h = (h ^ u64::from_le_bytes(tail)).wrapping_mul(K);
    h ^ (h >> 32)
}

/// Why this process's executable file could not be hashed.
#[derive(Clone, Debug, thiserror::Error)]
pub enum BinaryHashError {
    #[error("the executable's path: {0}")]
    Path(Arc<std::io::Error>),
    #[error("reading {}: {error}", exe.display())]
    Read {
        exe: std::path::PathBuf,
        error: Arc<std::io::Error>,
    },
}

/// The hash of this process's executable file (read once), or why it could not be read.
pub fn binary_hash() -> Result<u64, BinaryHashError> {
    static HASH: OnceLock<Result<u64, BinaryHashError>> = OnceLock::new();
    HASH.get_or_init(|| {
        let exe = std::env::current_exe().map_err(|e| BinaryHashError::Path(Arc::new(e)))?;
        let bytes = std::fs::read(&exe).map_err(|e| BinaryHashError::Read {
            exe: exe.clone(),
            error: Arc::new(e),
        })?;
        Ok(content_hash(&bytes))
    })
    .clone()
}

/// Why a rank could not get as far as its record: its start-up error's message, sent to rank 0
/// as text (a JSON string on the wire).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, thiserror::Error)]
#[error("{0}")]
pub struct StartupFailure(pub String);

impl From<BinaryHashError> for StartupFailure {
    fn from(e: BinaryHashError) -> Self {
        Self(e.to_string())
    }
}

/// The hash of a loaded scene: its triangles, materials, textures, lights, cameras and
/// environment, as the tracer will see them.
#[must_use]
pub fn scene_hash(scene: &crate::scene::Scene) -> u64 {
    let mut b: Vec<u8> = Vec::with_capacity(scene.triangles.len() * 100);
    for t in &scene.triangles {
        for v in t.p.iter().chain(&t.n) {
            b.extend(v.to_array().iter().flat_map(|x| x.to_le_bytes()));
        }
        b.extend(
            t.uv.iter()
                .flat_map(|v| v.to_array())
                .flat_map(f32::to_le_bytes),
        );
        b.extend(t.material.to_le_bytes());
    }
    for t in &scene.textures {
        b.extend(t.texels.iter().flatten());
        b.extend(format!("{}x{} {:?} {}", t.width, t.height, t.sampler, t.srgb).bytes());
    }
    match &scene.environment {
        crate::scene::Environment::Constant(c) => b.extend(format!("{c:?}").bytes()),
        crate::scene::Environment::Map(m) => {
            b.extend(format!("{}x{}", m.width, m.height).bytes());
            b.extend(
                m.texels
                    .iter()
                    .flat_map(|v| v.to_array())
                    .flat_map(f32::to_le_bytes),
            );
        }
    }
    let small = format!(
        "{:?}{:?}{:?}{:?}{:?}{:?}",
        scene.materials,
        scene.material_ext,
        scene.lights,
        scene.cameras,
        scene.orthographic_cameras,
        scene.vertex_extras.len()
    );
    b.extend(small.bytes());
    content_hash(&b)
}

/// What a rank is about to do, as named fields (compared in order).
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Identity {
    pub fields: Vec<(String, String)>,
}

impl Identity {
    /// Starts a record with the binary (hash and version) and the job's size.
    pub fn new(ranks: usize) -> Result<Self, BinaryHashError> {
        let mut id = Self::default();
        id.push(
            "binary",
            format!(
                "raygun {} ({:016x})",
                env!("CARGO_PKG_VERSION"),
                binary_hash()?
            ),
        );
        id.push("ranks", ranks.to_string());
        Ok(id)
    }

    /// Adds a field.
    pub fn push(&mut self, name: &str, value: impl Into<String>) {
        self.fields.push((name.to_owned(), value.into()));
    }

    /// Why `other` (rank `rank`'s record) differs from this one (rank 0's), if it does.
    #[must_use]
    pub fn mismatch(&self, other: &Self, rank: usize) -> Option<String> {
        for (name, mine) in &self.fields {
            let theirs = other.fields.iter().find(|(n, _)| n == name).map(|(_, v)| v);
            match theirs {
                None => return Some(format!("rank {rank} sent no {name}")),
                Some(v) if v != mine => return Some(describe(name, mine, v, rank)),
                Some(_) => {}
            }
        }
        other
            .fields
            .iter()
            .find(|(n, _)| !self.fields.iter().any(|(m, _)| m == n))
            .map(|(n, _)| format!("rank {rank} has a {n}, rank 0 has none"))
    }
}

/// A differing field: the tile map names the first tile whose owner differs; others quote
/// both values.
fn describe(name: &str, mine: &str, theirs: &str, rank: usize) -> String {
    if name == "tile map" {
        for (a, b) in mine.split(' ').zip(theirs.split(' ')) {
            if a != b {
                return format!(
                    "rank {rank}'s tile map differs from rank 0's: {b} on rank {rank}, {a} on rank 0"
                );
            }
        }
    }
    format!(
        "rank {rank}'s {name} differs from rank 0's: {} on rank {rank}, {} on rank 0",
        crate::messages::quote(theirs),
        crate::messages::quote(mine)
    )
}

/// Rank 0 gathers every rank's record (or its start-up error) and answers with one verdict;
/// every rank returns it: `Ok` to go on, or the reasons, each naming a rank.
pub fn handshake(
    cluster: &mut Cluster,
    mine: Result<Identity, StartupFailure>,
) -> Result<(), ClusterError> {
    let record: Result<Identity, StartupFailure> = mine;
    let bytes = serde_json::to_vec(&record).expect("a record serialises");
    let gathered = cluster.gather("the start-up check", bytes)?;
    let verdict = match gathered {
        Some(all) => {
            let mut problems = Vec::new();
            let decoded: Vec<Result<Identity, StartupFailure>> = all
                .iter()
                .map(|b| {
                    serde_json::from_slice(b).unwrap_or_else(|e| {
                        Err(StartupFailure(format!("an unreadable record ({e})")))
                    })
                })
                .collect();
            for (r, d) in decoded.iter().enumerate() {
                match (d, &decoded[0]) {
                    (Err(e), _) => problems.push(format!("rank {r} could not start: {e}")),
                    (Ok(id), Ok(root)) if r > 0 => problems.extend(root.mismatch(id, r)),
                    _ => {}
                }
            }
            problems.join("; ")
        }
        None => String::new(),
    };
    let verdict = cluster.broadcast("the start-up verdict", verdict.into_bytes())?;
    if verdict.is_empty() {
        Ok(())
    } else {
        Err(ClusterError::Rejected(
            String::from_utf8_lossy(&verdict).into_owned(),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hash_tells_apart_lengths_and_single_bits() {
        let a = content_hash(b"raygun cluster");
        assert_eq!(a, content_hash(b"raygun cluster"));
        assert_ne!(a, content_hash(b"raygun clustes"));
        assert_ne!(content_hash(b""), content_hash(&[0]));
        assert_ne!(content_hash(&[0; 8]), content_hash(&[0; 9]));
    }

    #[test]
    fn a_mismatch_names_the_rank_and_the_field() {
        let mut a = Identity::default();
        a.push("display model", "hornet");
        a.push("tile map", "c0r0=0 c1r0=1");
        let mut b = a.clone();
        assert_eq!(a.mismatch(&b, 1), None);
        b.fields[1].1 = "c0r0=0 c1r0=0".into();
        let m = a.mismatch(&b, 2).unwrap();
        assert!(
            m.contains("rank 2's tile map") && m.contains("c1r0=0 on rank 2, c1r0=1 on rank 0"),
            "{m}"
        );
        b.fields[0].1 = "desktop-27in-4k".into();
        let m = a.mismatch(&b, 1).unwrap();
        assert!(m.contains("rank 1's display model"), "{m}");
    }
}
