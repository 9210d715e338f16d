//! The MPI backend of [`Exchange`] (the `cluster` feature): rsmpi over the system's MPI
//! (Debian's OpenMPI), started by `mpirun`.
//!
//! A round posts its sends as non-blocking requests, then receives from each expected rank
//! in turn (a blocking matched probe and receive: the message's length needs no second
//! message) and waits for its sends. Sends posted for later ([`Lane::Later`]) keep their
//! buffers and requests here until the collect on that lane waits for them; each lane is its
//! own tag, so MPI matches a receive with its lane's next message only. MPI has no deadline
//! on a blocking call, so a watchdog thread holds the deadline of the wait in progress: past
//! it, the thread prints which rank did not answer and ends this process without MPI's
//! finalisation, and `mpirun`, seeing a rank end so, ends every other (the MPI standard leaves
//! a hung peer's fate to the implementation; OpenMPI's mpirun kills the job when a rank exits
//! unfinalised or non-zero). The watchdog never calls MPI, so the main thread is the only one
//! that does (`Threading::Funneled`).

use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use mpi::environment::Universe;
use mpi::point_to_point::{Destination, Source};
use mpi::request::{Request, StaticScope};
use mpi::topology::{Communicator, SimpleCommunicator};

use super::exchange::{Exchange, ExchangeError, Lane, Traffic};

/// The tag of a lane's messages (rounds on a lane are told apart by their order).
fn tag(lane: Lane) -> i32 {
    0x7a9 + lane as i32
}

/// How long a rank that ends waits for its last sends to be taken before giving up.
const LAST_SENDS: Duration = Duration::from_secs(60);

/// A send in progress: its request, the rank it goes to, and its buffer, owned here until the
/// request completes.
struct Sending {
    lane: Lane,
    dest: usize,
    request: Request<'static, [u8], StaticScope>,
    buffer: *mut [u8],
}

impl Sending {
    /// Waits for the send to be taken, then frees its buffer.
    fn finish(self) {
        self.request.wait();
        // SAFETY: `buffer` came from `Box::leak` in `post`; the request that borrowed it has
        // completed (and is gone), so this is the only reference.
        drop(unsafe { Box::from_raw(self.buffer) });
    }
}

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
    /// Sends posted and not yet waited for, oldest first.
    sending: Vec<Sending>,
    /// Finalises MPI when dropped: last.
    _universe: Universe,
}

impl Drop for Mpi {
    /// A request must complete before MPI is finalised: the last sends are waited for (under
    /// the watchdog, so a peer that is gone cannot hang the end).
    fn drop(&mut self) {
        for s in std::mem::take(&mut self.sending) {
            self.watchdog.arm(
                Instant::now() + LAST_SENDS,
                format!("rank {} did not take this rank's last message", s.dest),
            );
            s.finish();
        }
        self.watchdog.disarm();
    }
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
            sending: Vec::new(),
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

    fn post(
        &mut self,
        sends: Vec<(usize, Vec<u8>)>,
        lane: Lane,
        what: &str,
    ) -> Result<(), ExchangeError> {
        if let Some((dest, b)) = sends.iter().find(|(_, b)| i32::try_from(b.len()).is_err()) {
            return Err(ExchangeError::Mpi(format!(
                "{what}: a message of {} bytes to rank {dest} is over MPI's 2³¹ − 1",
                b.len()
            )));
        }
        self.traffic.count_sent(&sends);
        for (dest, bytes) in sends {
            let buffer: &'static mut [u8] = Box::leak(bytes.into_boxed_slice());
            let raw: *mut [u8] = buffer;
            // SAFETY: `raw` points at the leaked buffer, which stays allocated until
            // `Sending::finish` frees it after the request has completed; nothing writes it
            // meanwhile.
            let shared: &'static [u8] = unsafe { &*raw };
            let request = self
                .world
                .process_at_rank(dest as i32)
                .immediate_send_with_tag(StaticScope, shared, tag(lane));
            self.sending.push(Sending {
                lane,
                dest,
                request,
                buffer: raw,
            });
        }
        Ok(())
    }

    fn collect(
        &mut self,
        from: &[usize],
        lane: Lane,
        what: &str,
        wait: Duration,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        let deadline = Instant::now() + wait;
        let timeout = |rank: usize| ExchangeError::timeout(rank, wait, what).to_string();
        let mut got = Vec::with_capacity(from.len());
        for &src in from {
            self.watchdog.arm(deadline, timeout(src));
            let (bytes, _) = self
                .world
                .process_at_rank(src as i32)
                .receive_vec_with_tag::<u8>(tag(lane));
            got.push(bytes);
        }
        let (mine, others): (Vec<_>, Vec<_>) = std::mem::take(&mut self.sending)
            .into_iter()
            .partition(|s| s.lane == lane);
        self.sending = others;
        for s in mine {
            self.watchdog.arm(deadline, timeout(s.dest));
            s.finish();
        }
        self.watchdog.disarm();
        self.traffic.count_received(&got);
        Ok(got)
    }

    fn traffic(&self) -> Traffic {
        self.traffic
    }

    fn abort(&self, code: i32) -> ! {
        self.world.abort(code)
    }
}
