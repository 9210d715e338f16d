//! The MPI backend of [`Exchange`] (the `cluster` feature): rsmpi over the system's MPI
//! (Debian's OpenMPI), started by `mpirun`.
//!
//! A round posts its sends as non-blocking requests, then receives from each expected rank
//! in turn (a blocking matched probe and receive: the message's length needs no second
//! message) and waits for its sends. MPI has no deadline on a blocking call, so a watchdog
//! thread holds the deadline of the wait in progress: past it, the thread prints which rank did
//! not answer and ends this process without MPI's finalisation, and `mpirun`, seeing a rank end
//! so, ends every other (the MPI standard leaves a hung peer's fate to the implementation;
//! OpenMPI's mpirun kills the job when a rank exits unfinalised or non-zero). The watchdog
//! never calls MPI, so the main thread is the only one that does (`Threading::Funneled`).

use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use mpi::environment::Universe;
use mpi::point_to_point::{Destination, Source};
use mpi::topology::{Communicator, SimpleCommunicator};

use super::exchange::{Exchange, ExchangeError, Traffic};

/// The tag of every message (rounds are told apart by their order).
const TAG: i32 = 0x7a9;

/// How often the watchdog looks at the clock.
const WATCHDOG_TICK: Duration = Duration::from_millis(50);

/// The deadline of the wait in progress, and what to say when it passes.
struct Watchdog {
    armed: Mutex<Option<(Instant, String)>>,
}

impl Watchdog {
    fn arm(&self, deadline: Instant, message: String) {
        *self.armed.lock().expect("the watchdog's lock") = Some((deadline, message));
    }

    fn disarm(&self) {
        *self.armed.lock().expect("the watchdog's lock") = None;
    }
}

/// This process's rank of an MPI job.
pub struct Mpi {
    world: SimpleCommunicator,
    rank: usize,
    ranks: usize,
    traffic: Traffic,
    watchdog: Arc<Watchdog>,
    /// Finalises MPI when dropped: last.
    _universe: Universe,
}

impl Mpi {
    /// Initialises MPI (a process started without `mpirun` is a job of one rank).
    pub fn init() -> Result<Self, ExchangeError> {
        let (universe, _) = mpi::initialize_with_threading(mpi::Threading::Funneled)
            .ok_or_else(|| ExchangeError::Mpi("MPI was initialised already".into()))?;
        let world = universe.world();
        let rank = world.rank() as usize;
        let ranks = world.size() as usize;
        let watchdog = Arc::new(Watchdog {
            armed: Mutex::new(None),
        });
        let dog = Arc::clone(&watchdog);
        thread::Builder::new()
            .name("raygun cluster watchdog".into())
            .spawn(move || {
                loop {
                    thread::sleep(WATCHDOG_TICK);
                    let expired = dog
                        .armed
                        .lock()
                        .ok()
                        .and_then(|a| a.clone())
                        .filter(|(deadline, _)| Instant::now() >= *deadline);
                    if let Some((_, message)) = expired {
                        end_process(rank, &message);
                    }
                }
            })
            .map_err(|e| ExchangeError::Mpi(format!("starting the watchdog thread: {e}")))?;
        Ok(Self {
            world,
            rank,
            ranks,
            traffic: Traffic::default(),
            watchdog,
            _universe: universe,
        })
    }
}

/// Prints `message` as rank `rank`'s error and ends the process at once (no atexit handlers,
/// no MPI finalisation, which would wait for the peer that does not answer).
fn end_process(rank: usize, message: &str) -> ! {
    use std::io::Write;
    let mut err = std::io::stderr().lock();
    let _ = writeln!(
        err,
        "raygun: error: rank {rank}: cluster: {message}; ending the job"
    );
    let _ = err.flush();
    #[cfg(unix)]
    // SAFETY: `_exit` ends the process; nothing runs after it.
    unsafe {
        libc::_exit(3)
    }
    #[cfg(not(unix))]
    std::process::abort()
}

impl Exchange for Mpi {
    fn rank(&self) -> usize {
        self.rank
    }

    fn ranks(&self) -> usize {
        self.ranks
    }

    fn round(
        &mut self,
        sends: Vec<(usize, Vec<u8>)>,
        from: &[usize],
        what: &str,
        wait: Duration,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        if let Some((dest, b)) = sends.iter().find(|(_, b)| i32::try_from(b.len()).is_err()) {
            return Err(ExchangeError::Mpi(format!(
                "{what}: a message of {} bytes to rank {dest} is over MPI's 2³¹ − 1",
                b.len()
            )));
        }
        let deadline = Instant::now() + wait;
        let (world, dog) = (&self.world, &self.watchdog);
        let timeout = |rank: usize| {
            ExchangeError::Timeout {
                rank,
                seconds: wait.as_secs_f64(),
                what: what.to_owned(),
            }
            .to_string()
        };
        let mut got = Vec::with_capacity(from.len());
        mpi::request::scope(|scope| {
            let requests: Vec<_> = sends
                .iter()
                .map(|(dest, bytes)| {
                    world.process_at_rank(*dest as i32).immediate_send_with_tag(
                        scope,
                        &bytes[..],
                        TAG,
                    )
                })
                .collect();
            for &src in from {
                dog.arm(deadline, timeout(src));
                let (bytes, _) = world
                    .process_at_rank(src as i32)
                    .receive_vec_with_tag::<u8>(TAG);
                got.push(bytes);
            }
            for (request, (dest, _)) in requests.into_iter().zip(&sends) {
                dog.arm(deadline, timeout(*dest));
                request.wait();
            }
            dog.disarm();
        });
        self.traffic.count_round(&sends, &got);
        Ok(got)
    }

    fn traffic(&self) -> Traffic {
        self.traffic
    }

    fn abort(&self, code: i32) -> ! {
        self.world.abort(code)
    }
}
