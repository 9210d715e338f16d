//! `--cluster [--tile-owners FILE]`: one render across the ranks of an MPI job
//! (`mpirun -np N raygun render … --cluster`, DESIGN.md §12), with the `cluster` feature.

use std::path::PathBuf;

use anyhow::{Context, bail};

use crate::cluster::handshake::{Identity, StartupFailure, handshake};
use crate::cluster::owners::{BlockOwners, TileOwners};
use crate::cluster::{Cluster, ClusterError, DgiMode};
use crate::display::DisplayModel;
use crate::session::cluster::Fault;

/// The start-up check's words for where a rank traces: the kind of adapter (name and driver)
/// or the CPU twins, whatever their thread count. Ranks on different kinds would each be
/// right, but their samples differ in rounding, and the job would equal no one process.
pub fn trace_backend(backend: &crate::gpu::Backend) -> String {
    match backend {
        crate::gpu::Backend::Gpu(ctx) => format!(
            "GPU {} (driver {} {})",
            ctx.info.name, ctx.info.driver, ctx.info.driver_info
        ),
        crate::gpu::Backend::Cpu => "the CPU twins".into(),
    }
}

/// How to get `--cluster` where the binary was built without it.
pub const HOW_TO_GET_IT: &str = "this raygun was built without the `cluster` feature: install MPI \
     (Debian: apt-get install openmpi-bin libopenmpi-dev libclang-dev), build with \
     `cargo build --release --features cluster`, then run `mpirun -np N target/release/raygun … --cluster`";

/// The flags of a render across ranks.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct ClusterArgs {
    /// Render across the ranks of an MPI job: `mpirun -np N raygun … --cluster`. Rank 0 follows
    /// the guide and writes the outputs; every rank traces an interleaved share of each
    /// iteration's blocks; the image is bit for bit the one-process render's. Needs the
    /// `cluster` feature; each rank traces on its GPU or CPU twins as `--backend` says.
    #[arg(long)]
    pub cluster: bool,
    /// Which rank owns (accumulates) each display tile: lines `TILE_ID RANK`, `#` comments;
    /// every tile listed once (default: whole columns dealt evenly over the ranks).
    #[arg(long, value_name = "FILE", requires = "cluster")]
    pub tile_owners: Option<PathBuf>,
    /// Seconds a rank waits for another beyond its own work (plus twice that work) before it
    /// ends the job naming the rank that did not answer.
    #[arg(long, value_name = "S", default_value_t = 20.0, requires = "cluster")]
    pub cluster_timeout: f64,
    /// How a new ROI's DGI reaches the ranks: every rank computes it, rank 0 computes and
    /// broadcasts it, or every rank computes a share of its bands and sends them to the others.
    #[arg(long, value_enum, default_value_t = DgiMode::Compute, requires = "cluster")]
    pub cluster_dgi: DgiMode,
    /// Test hook: RANK:ITERATION:exit|hang makes that rank end (exit status 9) or stop
    /// answering at the start of that iteration.
    #[arg(long, value_name = "RANK:ITERATION:exit|hang", hide = true, value_parser = parse_fault, requires = "cluster")]
    pub cluster_fault: Option<Fault>,
}

/// Why a `--cluster-fault` value did not parse.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FaultParseError {
    #[error("{text:?}: expected RANK:ITERATION:exit|hang")]
    Form { text: String },
    #[error("{text:?}: {what} {value:?} is not a whole number")]
    NotANumber {
        text: String,
        what: &'static str,
        value: String,
    },
    #[error("{text:?}: the fault is exit or hang, not {kind:?}")]
    Kind { text: String, kind: String },
}

/// Parses `--cluster-fault`.
pub fn parse_fault(s: &str) -> Result<Fault, FaultParseError> {
    let parts: Vec<&str> = s.split(':').collect();
    let [rank, iteration, kind] = parts[..] else {
        return Err(FaultParseError::Form { text: s.to_owned() });
    };
    let num = |v: &str, what: &'static str| {
        v.parse::<u32>().map_err(|_| FaultParseError::NotANumber {
            text: s.to_owned(),
            what,
            value: v.to_owned(),
        })
    };
    let (rank, iteration) = (num(rank, "rank")? as usize, num(iteration, "iteration")?);
    match kind {
        "exit" => Ok(Fault::Exit { rank, iteration }),
        "hang" => Ok(Fault::Hang { rank, iteration }),
        _ => Err(FaultParseError::Kind {
            text: s.to_owned(),
            kind: kind.to_owned(),
        }),
    }
}

impl ClusterArgs {
    /// Checks the flags that need no job.
    pub fn validate(&self) -> anyhow::Result<()> {
        if !(self.cluster_timeout.is_finite() && self.cluster_timeout > 0.0) {
            bail!(
                "--cluster-timeout must be a positive number of seconds, not {}",
                crate::messages::number(self.cluster_timeout)
            );
        }
        Ok(())
    }
}

/// Joins the MPI job (a process started without `mpirun` is a job of one rank).
#[cfg(feature = "cluster")]
pub fn start(args: &ClusterArgs) -> anyhow::Result<Cluster> {
    args.validate()?;
    let mpi = crate::cluster::mpi::Mpi::init().context("--cluster")?;
    let rank = crate::cluster::exchange::Exchange::rank(&mpi);
    // mpirun ends every rank with SIGTERM when one of them dies: say so on this rank's way out.
    let _ = ctrlc::set_handler(move || {
        eprintln!(
            "raygun: error: rank {rank}: cluster: the job was ended from outside (SIGINT or SIGTERM; under mpirun: another rank died, and mpirun's message names it)"
        );
        std::process::exit(4);
    });
    Ok(Cluster::new(
        Box::new(mpi),
        std::time::Duration::from_secs_f64(args.cluster_timeout),
    ))
}

/// Without the `cluster` feature: says how to get it.
#[cfg(not(feature = "cluster"))]
pub fn start(args: &ClusterArgs) -> anyhow::Result<Cluster> {
    args.validate()?;
    bail!("--cluster: {HOW_TO_GET_IT}")
}

/// The block owners of a `size` image: from `--tile-owners` or whole columns of `model`, or
/// vertical strips without a display; the tile owners they were made from (with a display);
/// the tile map as the start-up check compares it.
pub fn block_owners(
    args: &ClusterArgs,
    model: Option<&DisplayModel>,
    size: [u32; 2],
    ranks: usize,
) -> anyhow::Result<(BlockOwners, Option<TileOwners>, String)> {
    match (model, &args.tile_owners) {
        (Some(m), file) => {
            let owners = match file {
                Some(f) => TileOwners::load(f, m, ranks).context("--tile-owners")?,
                None => TileOwners::columns(m, ranks),
            };
            let map = owners.describe(m);
            Ok((BlockOwners::of_display(m, &owners, size), Some(owners), map))
        }
        (None, Some(f)) => bail!(
            "--tile-owners {}: the tiles are a display's: this render has no --display",
            f.display()
        ),
        (None, None) => Ok((
            BlockOwners::strips(size, ranks),
            None,
            format!("{ranks} strips"),
        )),
    }
}

/// The start-up check's record of a render: `fields` after the binary and the job's size.
pub fn identity(ranks: usize, fields: &[(&str, String)]) -> Result<Identity, StartupFailure> {
    let mut id = Identity::new(ranks)?;
    for (name, value) in fields {
        id.push(name, value.clone());
    }
    Ok(id)
}

/// The display model as the check compares it: its name and the hash of its explicit form.
#[must_use]
pub fn model_field(model: &DisplayModel) -> String {
    format!(
        "{} ({:016x})",
        model.name(),
        crate::cluster::handshake::content_hash(model.to_json_pretty().as_bytes())
    )
}

/// Runs the start-up check with this rank's record (or the error that kept it from one): `Ok`
/// on every rank to go on; an error (the same on every rank) naming the ranks at fault.
pub fn check(c: &mut Cluster, mine: Result<Identity, StartupFailure>) -> anyhow::Result<()> {
    match handshake(c, mine) {
        Ok(()) => Ok(()),
        Err(ClusterError::Rejected(why)) => bail!("--cluster: rank {}: {why}", c.rank()),
        Err(e) => Err(anyhow::Error::new(e).context(format!("--cluster: rank {}", c.rank()))),
    }
}

/// After the check, an error on one rank ends the whole job: printed here, then MPI_Abort.
pub fn or_abort<T>(c: &Cluster, r: anyhow::Result<T>) -> T {
    match r {
        Ok(v) => v,
        Err(e) => {
            eprintln!(
                "raygun: error: rank {}: {}",
                c.rank(),
                crate::cli::error_chain(&e)
            );
            c.abort(1)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faults_parse_and_bad_ones_say_the_form() {
        assert_eq!(
            parse_fault("2:3:hang"),
            Ok(Fault::Hang {
                rank: 2,
                iteration: 3
            })
        );
        assert_eq!(
            parse_fault("0:0:exit"),
            Ok(Fault::Exit {
                rank: 0,
                iteration: 0
            })
        );
        for bad in ["2:3", "x:3:hang", "2:-1:exit", "2:3:crash"] {
            let e = parse_fault(bad).unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
    }

    #[test]
    fn tile_owners_need_a_display_and_strips_serve_a_plain_frame() {
        let args = ClusterArgs {
            cluster: true,
            tile_owners: Some(PathBuf::from("o.txt")),
            ..ClusterArgs::default()
        };
        let e = block_owners(&args, None, [64, 32], 2).unwrap_err();
        assert!(e.to_string().contains("no --display"), "{e}");
        let args = ClusterArgs {
            cluster: true,
            ..ClusterArgs::default()
        };
        let (b, tiles, map) = block_owners(&args, None, [64, 32], 2).unwrap();
        assert_eq!((b.owner, map.as_str()), (vec![0, 1], "2 strips"));
        assert!(tiles.is_none());
        let hornet = DisplayModel::open("hornet").unwrap().0;
        let (_, tiles, map) = block_owners(&args, Some(&hornet), [64, 32], 2).unwrap();
        assert_eq!(tiles, Some(TileOwners::columns(&hornet, 2)));
        assert!(
            map.starts_with("c0r0=0") && map.ends_with("c6r4=1"),
            "{map}"
        );
    }
}
