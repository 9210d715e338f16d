//! UDP listeners: bound to loopback unless told otherwise, with a source allow-list, a kernel
//! receive buffer of at least 64 KiB, and latest-state semantics.
//!
//! Latest-state semantics: the receive loop decodes every datagram and feeds it through the
//! interaction state machine at once (both cost microseconds), and publishes the resulting
//! ROI into one shared slot that the renderer reads whenever it starts a frame. There is no
//! queue between network and ROI, so the ROI can never lag behind a backlog and memory does
//! not grow with the input rate; if input ever outpaced decoding, the kernel buffer would drop
//! datagrams, which for poses (each one superseding the last) is the right loss.

use std::io;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use socket2::{Domain, Protocol as SockProtocol, Socket, Type};

use super::pipeline::Pipeline;
use crate::interaction::{RaySurface, RoiChange, RoiState};
use crate::tracking::event::TrackingEvent;
use crate::tracking::ingest::Protocol;
use crate::tracking::problems::ProblemLog;
use crate::tracking::replay::ReplayWriter;

/// Smallest kernel receive buffer accepted: one maximal OSC bundle must fit.
pub const MIN_RECV_BUFFER: usize = 64 * 1024;
pub use crate::tracking::replay::FLUSH_INTERVAL;

/// How a listener binds and whom it listens to.
#[derive(Clone, Debug, PartialEq)]
pub struct ListenerConfig {
    pub bind: SocketAddr,
    /// Binding anything but a loopback address exposes the listener to the network; it needs
    /// this explicit opt-in.
    pub allow_non_loopback: bool,
    /// Source addresses accepted; empty accepts every source.
    pub allow_from: Vec<IpAddr>,
    /// Kernel receive buffer (SO_RCVBUF) asked for, bytes.
    pub recv_buffer_bytes: usize,
    /// How often the receive loop wakes up to check whether it should stop.
    pub poll: Duration,
}

impl ListenerConfig {
    /// Loopback on `port` (0: any free port), 1 MiB receive buffer (~3000 DTrack frames).
    #[must_use]
    pub fn loopback(port: u16) -> Self {
        Self {
            bind: SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), port),
            allow_non_loopback: false,
            allow_from: Vec::new(),
            recv_buffer_bytes: 1 << 20,
            poll: Duration::from_millis(50),
        }
    }
}

/// Why a listener cannot start.
#[derive(Debug, thiserror::Error)]
pub enum UdpError {
    #[error(
        "refusing to bind {addr}: not a loopback address (listening on the network needs --allow-network)"
    )]
    NonLoopback { addr: SocketAddr },
    #[error("receive buffer of {bytes} bytes is below the {MIN_RECV_BUFFER}-byte minimum")]
    BufferTooSmall { bytes: usize },
    #[error("UDP socket {addr}: {source}")]
    Io {
        addr: SocketAddr,
        #[source]
        source: io::Error,
    },
}

/// What one receive call produced.
#[derive(Debug, PartialEq, Eq)]
pub enum Received<'a> {
    Datagram(&'a [u8], SocketAddr),
    /// From a source not on the allow-list; dropped.
    Rejected(SocketAddr),
    /// Nothing arrived within the poll interval.
    Idle,
}

/// A bound UDP socket with its receive buffer.
pub struct UdpSource {
    socket: UdpSocket,
    config: ListenerConfig,
    buf: Vec<u8>,
}

impl UdpSource {
    /// Binds according to `config`.
    pub fn bind(config: ListenerConfig) -> Result<Self, UdpError> {
        let addr = config.bind;
        if !addr.ip().is_loopback() && !config.allow_non_loopback {
            return Err(UdpError::NonLoopback { addr });
        }
        if config.recv_buffer_bytes < MIN_RECV_BUFFER {
            return Err(UdpError::BufferTooSmall {
                bytes: config.recv_buffer_bytes,
            });
        }
        let io_err = |source| UdpError::Io { addr, source };
        let socket = Socket::new(
            Domain::for_address(addr),
            Type::DGRAM,
            Some(SockProtocol::UDP),
        )
        .map_err(io_err)?;
        socket
            .set_recv_buffer_size(config.recv_buffer_bytes)
            .map_err(io_err)?;
        socket.bind(&addr.into()).map_err(io_err)?;
        let socket: UdpSocket = socket.into();
        socket.set_read_timeout(Some(config.poll)).map_err(io_err)?;
        Ok(Self {
            socket,
            config,
            // One byte more than the largest UDP payload, so nothing is ever cut silently.
            buf: vec![0; 65_536],
        })
    }

    /// The bound address (with the real port when 0 was asked for).
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// The kernel receive buffer actually granted (Linux reports twice the request).
    pub fn recv_buffer_bytes(&self) -> io::Result<usize> {
        socket2::SockRef::from(&self.socket).recv_buffer_size()
    }

    /// Waits up to the poll interval for one datagram (`Idle` when none came or a signal
    /// interrupted the wait).
    pub fn recv(&mut self) -> io::Result<Received<'_>> {
        match self.socket.recv_from(&mut self.buf) {
            Ok((n, from)) => {
                if !self.config.allow_from.is_empty()
                    && !self.config.allow_from.contains(&from.ip())
                {
                    Ok(Received::Rejected(from))
                } else {
                    Ok(Received::Datagram(&self.buf[..n], from))
                }
            }
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock
                        | io::ErrorKind::TimedOut
                        // A signal (Ctrl-C asking the recorder to stop) interrupted the wait:
                        // the caller's loop checks its stop flag next.
                        | io::ErrorKind::Interrupted
                ) =>
            {
                Ok(Received::Idle)
            }
            Err(e) => Err(e),
        }
    }
}

/// What the receive loop publishes: the latest ROI and counters. Readers lock briefly.
#[derive(Clone, Debug, Default)]
pub struct LiveSnapshot {
    pub roi: Option<RoiState>,
    /// Increments with every ROI change.
    pub version: u64,
    /// Datagrams received, from any source (rejected ones included).
    pub datagrams: u64,
    pub problems: ProblemLog,
}

/// The shared slot between the receive loop and its readers.
#[derive(Debug, Default)]
pub struct Live {
    snapshot: Mutex<LiveSnapshot>,
}

impl Live {
    /// A copy of the current state.
    #[must_use]
    pub fn snapshot(&self) -> LiveSnapshot {
        self.snapshot.lock().map(|s| s.clone()).unwrap_or_default()
    }

    /// Datagrams handled so far (cheaper than a snapshot).
    #[must_use]
    pub fn datagrams(&self) -> u64 {
        self.snapshot.lock().map(|s| s.datagrams).unwrap_or(0)
    }

    /// What a receive loop publishes after one input: `reads` more inputs handled, the ROI
    /// after the last of `n_changes` changes (if any), the problem counts when they changed.
    pub(crate) fn publish(
        &self,
        reads: u64,
        latest: Option<RoiState>,
        n_changes: u64,
        problems: Option<&ProblemLog>,
    ) -> io::Result<()> {
        let Ok(mut snap) = self.snapshot.lock() else {
            return Err(io::Error::other("live state lock poisoned"));
        };
        snap.datagrams += reads;
        if latest.is_some() {
            snap.roi = latest;
            snap.version += n_changes;
        }
        if let Some(p) = problems {
            snap.problems = p.clone();
        }
        Ok(())
    }
}

/// Receives on `source` until `stop` is set: every datagram goes through `pipeline`; its
/// events and the ROI changes they caused are passed to `on_datagram`, and the latest ROI is
/// published in `live`.
pub fn run_live(
    source: &mut UdpSource,
    protocol: Protocol,
    pipeline: &mut Pipeline,
    surface: &dyn RaySurface,
    stop: &AtomicBool,
    live: &Live,
    mut on_datagram: impl FnMut(&[TrackingEvent], &[RoiChange]),
) -> io::Result<()> {
    let start = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        let problems_before = pipeline.ingest.problems.total();
        let t = start.elapsed().as_secs_f64();
        let mut latest: Option<RoiState> = None;
        let mut n_changes = 0;
        match source.recv()? {
            Received::Idle => continue,
            Received::Rejected(from) => {
                pipeline.ingest.problems.report(
                    "udp_rejected_source",
                    format_args!("datagram from {from} is not on the allow-list"),
                );
            }
            Received::Datagram(bytes, _) => {
                let (events, changes) = pipeline.datagram(protocol, bytes, t, surface);
                on_datagram(events, changes);
                latest = changes.last().map(|c| c.roi.clone());
                n_changes = changes.len();
            }
        }
        let problems = (pipeline.ingest.problems.total() != problems_before)
            .then_some(&pipeline.ingest.problems);
        live.publish(1, latest, n_changes as u64, problems)?;
    }
    Ok(())
}

/// Records every datagram from an allowed source into a replay until `stop` is set or
/// `max_duration` has passed. Returns the number of datagrams written.
pub fn record<W: io::Write>(
    source: &mut UdpSource,
    protocol: Protocol,
    writer: &mut ReplayWriter<W>,
    stop: &AtomicBool,
    max_duration: Option<Duration>,
    problems: &mut ProblemLog,
) -> io::Result<u64> {
    let start = Instant::now();
    let mut last_flush = start;
    let mut n = 0;
    while !stop.load(Ordering::Relaxed) && max_duration.is_none_or(|d| start.elapsed() < d) {
        let t = start.elapsed().as_secs_f64();
        match source.recv()? {
            Received::Idle => {}
            Received::Rejected(from) => {
                problems.report(
                    "udp_rejected_source",
                    format_args!("datagram from {from} is not on the allow-list"),
                );
            }
            Received::Datagram(bytes, _) => {
                writer.datagram(t, protocol, bytes)?;
                n += 1;
            }
        }
        // Under a steady stream as when the line is quiet: a killed recorder keeps everything
        // up to the last flush.
        if last_flush.elapsed() >= FLUSH_INTERVAL {
            writer.flush()?;
            last_flush = Instant::now();
        }
    }
    writer.flush()?;
    Ok(n)
}
