//! The live VRPN client: connects to `DEVICE@HOST[:PORT]` directly over TCP or by VRPN's
//! classic UDP set-up, reconnects with back-off when the server goes away, and hands on every
//! read raw, with its channel — decoding is the pipeline's job ([`VrpnDecoder`](crate::tracking::vrpn::VrpnDecoder) inside
//! [`Ingest`]), so that a recording of these reads replays exactly.
//!
//! Classic set-up (`DEVICE@HOST`, as VRPN's own clients default to):
//! 1. the client listens on a TCP port and on a UDP port, and sends the server's UDP port a
//!    "lob" datagram `"<ip> <tcp port>\0"` (again every second until answered);
//! 2. the server connects back; both sides write their cookie at once, then read the other's;
//! 3. the client sends a UDP description (type −3, sender field = its UDP port, payload its
//!    IP); from then on the server sends Pos_Quat and analog messages by UDP, buttons and
//!    descriptions by TCP.
//!
//! `DEVICE@tcp://HOST` connects straight to the TCP port; the server then sends everything
//! over TCP.
//!
//! Like the UDP listeners, the client is loopback-only unless told otherwise: a server that
//! is not on this machine needs [`VrpnClientConfig::allow_non_loopback`] (in the classic mode
//! the client opens listening ports on that network). The server's callback and its UDP
//! datagrams are accepted only from the server's address.

use std::io::{self, Read, Write};
use std::net::{
    IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr, TcpListener, TcpStream, ToSocketAddrs, UdpSocket,
};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use socket2::{Domain, Protocol as SockProtocol, SockRef, Socket, TcpKeepalive, Type};

use super::pipeline::Pipeline;
use super::udp::Live;
use crate::interaction::{RaySurface, RoiChange};
use crate::tracking::event::TrackingEvent;
use crate::tracking::ingest::{Ingest, Protocol};
use crate::tracking::problems::ProblemLog;
use crate::tracking::replay::ReplayWriter;
use crate::tracking::vrpn::config::{Transport, VrpnAddress};
use crate::tracking::vrpn::wire::{COOKIE_LEN, VrpnTime, check_cookie, encode, system};

/// How the client connects.
#[derive(Clone, Debug, PartialEq)]
pub struct VrpnClientConfig {
    pub address: VrpnAddress,
    /// Connecting to a server that is not on this machine exposes the client's ports to the
    /// network; it needs this explicit opt-in.
    pub allow_non_loopback: bool,
    /// Longest wait for a TCP connection to the server.
    pub connect_timeout: Duration,
    /// Longest wait for the server's cookie (and, in the classic mode, its callback): a server
    /// that accepts and then sends nothing is dropped after this.
    pub handshake_timeout: Duration,
    /// How long one [`VrpnSource::poll`] waits for input before returning
    /// [`VrpnPoll::Idle`] (so the caller can check its stop flag).
    pub poll: Duration,
    /// Connect again when the connection ends (viewing); off, the first end is the end of the
    /// session (recording).
    pub reconnect: bool,
    /// Wait before the first reconnection attempt; doubled after each failure up to
    /// `backoff_max`, reset once a server's cookie arrives.
    pub backoff_min: Duration,
    pub backoff_max: Duration,
    /// Kernel receive buffer (SO_RCVBUF) asked for on the UDP socket.
    pub udp_recv_buffer_bytes: usize,
}

impl VrpnClientConfig {
    /// Defaults: loopback only, 2 s to connect, 3 s for the handshake, 50 ms polls,
    /// reconnecting after 0.1 s, 0.2 s, … up to 5 s, 1 MiB UDP buffer.
    #[must_use]
    pub fn new(address: VrpnAddress) -> Self {
        Self {
            address,
            allow_non_loopback: false,
            connect_timeout: Duration::from_secs(2),
            handshake_timeout: Duration::from_secs(3),
            poll: Duration::from_millis(50),
            reconnect: true,
            backoff_min: Duration::from_millis(100),
            backoff_max: Duration::from_secs(5),
            udp_recv_buffer_bytes: 1 << 20,
        }
    }
}

/// Why a client cannot start.
#[derive(Debug, thiserror::Error)]
pub enum VrpnClientError {
    #[error("VRPN server {address}: cannot resolve its host: {source}")]
    Resolve {
        address: String,
        #[source]
        source: io::Error,
    },
    #[error(
        "VRPN server {address} is at {ip}, not a loopback address: pass --allow-network to connect to a server on another machine"
    )]
    NonLoopback { address: String, ip: IpAddr },
    #[error(
        "VRPN server {address}: the classic UDP set-up needs an IPv4 address (found only {ip}); use DEVICE@tcp://HOST"
    )]
    NeedsIpv4 { address: String, ip: IpAddr },
    #[error("VRPN client setting `{field}`: {reason}")]
    Invalid { field: &'static str, reason: String },
}

/// What one poll produced.
#[derive(Debug, PartialEq, Eq)]
pub enum VrpnPoll<'a> {
    /// Bytes read from the TCP connection (the first 24 of a connection are the cookie).
    Tcp(&'a [u8]),
    /// One UDP datagram from the server.
    Udp(&'a [u8]),
    /// The connection ended (the server closed it, a read failed, the handshake timed out,
    /// or it was dropped): decode this as a zero-byte TCP read.
    Closed,
    /// Nothing arrived within the poll interval (or the client is waiting to reconnect).
    Idle,
    /// The session is over: the connection ended and reconnecting is off.
    Ended,
}

impl VrpnPoll<'_> {
    /// The protocol and bytes to hand to [`Pipeline::datagram`] or to a replay writer
    /// ([`VrpnPoll::Closed`] is an empty TCP read); `None` for `Idle` and `Ended`.
    #[must_use]
    pub fn datagram(&self) -> Option<(Protocol, &[u8])> {
        match self {
            VrpnPoll::Tcp(b) => Some((Protocol::VrpnTcp, b)),
            VrpnPoll::Udp(b) => Some((Protocol::VrpnUdp, b)),
            VrpnPoll::Closed => Some((Protocol::VrpnTcp, &[])),
            VrpnPoll::Idle | VrpnPoll::Ended => None,
        }
    }
}

struct Lob {
    listener: TcpListener,
    udp: UdpSocket,
    lobber: UdpSocket,
    message: Vec<u8>,
    next_lob: Instant,
    deadline: Instant,
}

struct Conn {
    tcp: TcpStream,
    udp: Option<UdpSocket>,
    cookie: [u8; COOKIE_LEN],
    cookie_have: usize,
    deadline: Instant,
    close_next: bool,
}

enum State {
    Waiting { until: Instant },
    Lobbing(Box<Lob>),
    Connected(Box<Conn>),
    Ended,
}

/// A VRPN connection that can be polled: see the module documentation. It is `Send`, so a
/// viewer can poll it on its own thread ([`run_live`]).
pub struct VrpnSource {
    config: VrpnClientConfig,
    server: SocketAddr,
    local_ip: IpAddr,
    state: State,
    backoff: Duration,
    buf: Vec<u8>,
    connections: u64,
}

impl VrpnSource {
    /// Resolves the server and checks the loopback rule; the first connection attempt is made
    /// by the first [`Self::poll`].
    pub fn new(config: VrpnClientConfig) -> Result<Self, VrpnClientError> {
        let a = &config.address;
        let address = a.to_string();
        if config.poll.is_zero()
            || config.backoff_min.is_zero()
            || config.backoff_max < config.backoff_min
        {
            return Err(VrpnClientError::Invalid {
                field: "poll / backoff",
                reason:
                    "the poll interval and back-off must be positive, backoff_max ≥ backoff_min"
                        .into(),
            });
        }
        let addrs: Vec<SocketAddr> = (a.host.as_str(), a.port)
            .to_socket_addrs()
            .map_err(|source| VrpnClientError::Resolve {
                address: address.clone(),
                source,
            })?
            .collect();
        let server = match a.transport {
            Transport::Udp => match addrs.iter().find(|s| s.is_ipv4()) {
                Some(s) => *s,
                None => {
                    return Err(match addrs.first() {
                        Some(s) => VrpnClientError::NeedsIpv4 {
                            address,
                            ip: s.ip(),
                        },
                        None => VrpnClientError::Resolve {
                            address,
                            source: io::Error::other("no addresses"),
                        },
                    });
                }
            },
            Transport::Tcp => *addrs
                .iter()
                .find(|s| s.is_ipv4())
                .or(addrs.first())
                .ok_or_else(|| VrpnClientError::Resolve {
                    address: address.clone(),
                    source: io::Error::other("no addresses"),
                })?,
        };
        if !server.ip().is_loopback() && !config.allow_non_loopback {
            return Err(VrpnClientError::NonLoopback {
                address,
                ip: server.ip(),
            });
        }
        let local_ip = if server.ip().is_loopback() {
            server.ip()
        } else {
            // The address this machine uses towards the server: what it must tell the server
            // to call back, and where to listen.
            let any = if server.is_ipv4() {
                IpAddr::V4(Ipv4Addr::UNSPECIFIED)
            } else {
                IpAddr::V6(Ipv6Addr::UNSPECIFIED)
            };
            UdpSocket::bind((any, 0))
                .and_then(|s| {
                    s.connect(server)?;
                    s.local_addr()
                })
                .map(|a| a.ip())
                .map_err(|source| VrpnClientError::Resolve {
                    address: address.clone(),
                    source,
                })?
        };
        let backoff = config.backoff_min;
        Ok(Self {
            config,
            server,
            local_ip,
            state: State::Waiting {
                until: Instant::now(),
            },
            backoff,
            buf: vec![0; 65_536],
            connections: 0,
        })
    }

    /// The server's address.
    #[must_use]
    pub fn server(&self) -> SocketAddr {
        self.server
    }

    #[must_use]
    pub fn config(&self) -> &VrpnClientConfig {
        &self.config
    }

    /// Whether a connection is up (its handshake may still be running).
    #[must_use]
    pub fn is_connected(&self) -> bool {
        matches!(self.state, State::Connected(_))
    }

    /// Connections made so far (TCP connected or called back).
    #[must_use]
    pub fn connections(&self) -> u64 {
        self.connections
    }

    /// Drops the current connection (the decoder found the stream broken): the next poll
    /// returns [`VrpnPoll::Closed`], then the client reconnects after its back-off.
    pub fn drop_connection(&mut self) {
        match &mut self.state {
            State::Connected(c) => c.close_next = true,
            State::Lobbing(_) => self.retry_later(),
            State::Waiting { .. } | State::Ended => {}
        }
    }

    fn retry_later(&mut self) {
        self.state = if self.config.reconnect {
            let until = Instant::now() + self.backoff;
            self.backoff = (self.backoff * 2).min(self.config.backoff_max);
            State::Waiting { until }
        } else {
            State::Ended
        };
    }

    /// Waits up to the poll interval for input and returns it; connects, reconnects and
    /// times out handshakes on the way (a TCP connection attempt may block for up to
    /// [`VrpnClientConfig::connect_timeout`]; on loopback a refusal is immediate). Problems of the connection (refused, lost, no cookie,
    /// datagrams from strangers) are counted in `problems`; problems of the bytes are the
    /// decoder's.
    pub fn poll(&mut self, problems: &mut ProblemLog) -> io::Result<VrpnPoll<'_>> {
        let now = Instant::now();
        match &self.state {
            State::Ended => Ok(VrpnPoll::Ended),
            State::Waiting { until } => {
                let until = *until;
                if now >= until {
                    self.start(problems);
                } else {
                    std::thread::sleep((until - now).min(self.config.poll));
                }
                Ok(VrpnPoll::Idle)
            }
            State::Lobbing(_) => {
                self.poll_lob(problems);
                Ok(VrpnPoll::Idle)
            }
            State::Connected(_) => self.poll_conn(problems),
        }
    }

    fn address(&self) -> String {
        self.config.address.to_string()
    }

    fn start(&mut self, problems: &mut ProblemLog) {
        let result = match self.config.address.transport {
            Transport::Tcp => TcpStream::connect_timeout(&self.server, self.config.connect_timeout)
                .and_then(|tcp| self.connected(tcp, None)),
            Transport::Udp => self.start_lob(),
        };
        if let Err(e) = result {
            problems.report(
                "vrpn_connect_failed",
                format_args!("VRPN server {} ({}): {e}", self.address(), self.server),
            );
            self.retry_later();
        }
    }

    fn start_lob(&mut self) -> io::Result<()> {
        let listener = TcpListener::bind((self.local_ip, 0))?;
        listener.set_nonblocking(true)?;
        let udp = bind_udp(
            SocketAddr::new(self.local_ip, 0),
            self.config.udp_recv_buffer_bytes,
        )?;
        let lobber = UdpSocket::bind((self.local_ip, 0))?;
        let port = listener.local_addr()?.port();
        let mut message = format!("{} {port}", self.local_ip).into_bytes();
        message.push(0);
        let now = Instant::now();
        self.state = State::Lobbing(Box::new(Lob {
            listener,
            udp,
            lobber,
            message,
            next_lob: now,
            deadline: now + self.config.handshake_timeout,
        }));
        Ok(())
    }

    fn poll_lob(&mut self, problems: &mut ProblemLog) {
        let State::Lobbing(lob) = &mut self.state else {
            return;
        };
        let now = Instant::now();
        if now >= lob.next_lob {
            if let Err(e) = lob.lobber.send_to(&lob.message, self.server) {
                problems.report(
                    "vrpn_connect_failed",
                    format_args!(
                        "VRPN server {}: sending the UDP connection request: {e}",
                        self.server
                    ),
                );
            }
            lob.next_lob = now + Duration::from_secs(1);
        }
        let wait = lob
            .deadline
            .min(lob.next_lob)
            .saturating_duration_since(now)
            .min(self.config.poll);
        if let Err(e) = wait_readable(&[Sock::Listener(&lob.listener)], wait) {
            problems.report(
                "vrpn_connect_failed",
                format_args!("waiting for the server's callback: {e}"),
            );
        }
        match lob.listener.accept() {
            Ok((tcp, peer)) if peer.ip() == self.server.ip() => {
                let State::Lobbing(lob) = std::mem::replace(&mut self.state, State::Ended) else {
                    return;
                };
                if let Err(e) = self.connected(tcp, Some(lob.udp)) {
                    problems.report(
                        "vrpn_connect_failed",
                        format_args!("VRPN server {} called back but: {e}", self.server),
                    );
                    self.retry_later();
                }
            }
            Ok((_, peer)) => problems.report(
                "vrpn_callback_rejected",
                format_args!(
                    "a connection from {peer} is not the server {}; closed",
                    self.server.ip()
                ),
            ),
            Err(e) if is_transient(&e) => {
                if Instant::now() >= lob.deadline {
                    problems.report(
                        "vrpn_no_callback",
                        format_args!(
                            "VRPN server {} did not connect back within {:?} (is it running, and can it reach {}?)",
                            self.address(),
                            self.config.handshake_timeout,
                            self.local_ip
                        ),
                    );
                    self.retry_later();
                }
            }
            Err(e) => {
                problems.report(
                    "vrpn_connect_failed",
                    format_args!("accepting the server's callback: {e}"),
                );
                self.retry_later();
            }
        }
    }

    /// A TCP connection is up: write our cookie at once (a real server writes its own right
    /// after accepting, without waiting for ours).
    fn connected(&mut self, mut tcp: TcpStream, udp: Option<UdpSocket>) -> io::Result<()> {
        tcp.set_nodelay(true)?;
        // A server machine that dies leaves the connection open forever; keepalive probes
        // notice within about 2 s + the system's probe count × 1 s.
        let keepalive = TcpKeepalive::new().with_time(Duration::from_secs(2));
        #[cfg(any(target_os = "linux", target_os = "macos", target_os = "windows"))]
        let keepalive = keepalive.with_interval(Duration::from_secs(1));
        SockRef::from(&tcp).set_tcp_keepalive(&keepalive)?;
        tcp.set_write_timeout(Some(self.config.connect_timeout))?;
        tcp.write_all(&encode::cookie())?;
        tcp.set_nonblocking(true)?;
        if let Some(u) = &udp {
            u.set_nonblocking(true)?;
        }
        self.connections += 1;
        self.state = State::Connected(Box::new(Conn {
            tcp,
            udp,
            cookie: [0; COOKIE_LEN],
            cookie_have: 0,
            deadline: Instant::now() + self.config.handshake_timeout,
            close_next: false,
        }));
        Ok(())
    }

    fn end(&mut self) -> io::Result<VrpnPoll<'_>> {
        self.retry_later();
        Ok(VrpnPoll::Closed)
    }

    fn poll_conn(&mut self, problems: &mut ProblemLog) -> io::Result<VrpnPoll<'_>> {
        let State::Connected(c) = &mut self.state else {
            return Ok(VrpnPoll::Idle);
        };
        if c.close_next {
            return self.end();
        }
        let now = Instant::now();
        let handshaking = c.cookie_have < COOKIE_LEN;
        if handshaking && now >= c.deadline {
            problems.report(
                "vrpn_no_cookie",
                format_args!(
                    "VRPN server {}: no cookie within {:?} of connecting ({} of 24 bytes); reconnecting",
                    self.config.address, self.config.handshake_timeout, c.cookie_have
                ),
            );
            return self.end();
        }
        let mut wait = self.config.poll;
        if handshaking {
            wait = wait.min(c.deadline - now);
        }
        let socks: Vec<Sock<'_>> = std::iter::once(Sock::Tcp(&c.tcp))
            .chain(c.udp.as_ref().map(Sock::Udp))
            .collect();
        if let Err(e) = wait_readable(&socks, wait) {
            problems.report(
                "vrpn_connection_lost",
                format_args!("waiting for input: {e}"),
            );
            return self.end();
        }
        // TCP first: descriptions must be decoded before the datagrams that use their ids.
        match c.tcp.read(&mut self.buf) {
            Ok(0) => {
                if self.config.reconnect {
                    problems.report(
                        "vrpn_connection_lost",
                        format_args!(
                            "VRPN server {} closed the connection; reconnecting",
                            self.config.address
                        ),
                    );
                }
                return self.end();
            }
            Ok(n) => {
                if c.cookie_have < COOKIE_LEN {
                    let take = (COOKIE_LEN - c.cookie_have).min(n);
                    c.cookie[c.cookie_have..c.cookie_have + take]
                        .copy_from_slice(&self.buf[..take]);
                    c.cookie_have += take;
                    if c.cookie_have == COOKIE_LEN {
                        if check_cookie(&c.cookie).is_ok() {
                            self.backoff = self.config.backoff_min;
                            if let Some(u) = &c.udp {
                                // Ask for UDP: sender field = our UDP port, payload our IP.
                                let port = u.local_addr()?.port();
                                let mut msg = Vec::with_capacity(48);
                                encode::message(
                                    &mut msg,
                                    now_stamp(),
                                    i32::from(port),
                                    system::UDP_DESCRIPTION,
                                    0,
                                    &encode::udp_description(&self.local_ip.to_string()),
                                );
                                if let Err(e) = write_all_nonblocking(&mut c.tcp, &msg) {
                                    problems.report(
                                        "vrpn_connection_lost",
                                        format_args!("sending the UDP description: {e}"),
                                    );
                                    c.close_next = true;
                                }
                            }
                        } else {
                            // The decoder reports what is wrong; the connection is useless.
                            c.close_next = true;
                        }
                    }
                }
                return Ok(VrpnPoll::Tcp(&self.buf[..n]));
            }
            Err(e) if is_transient(&e) => {}
            Err(e) => {
                problems.report(
                    "vrpn_connection_lost",
                    format_args!("VRPN server {}: {e}; reconnecting", self.config.address),
                );
                return self.end();
            }
        }
        if let Some(u) = &c.udp {
            match u.recv_from(&mut self.buf) {
                Ok((n, from)) if from.ip() == self.server.ip() => {
                    return Ok(VrpnPoll::Udp(&self.buf[..n]));
                }
                Ok((_, from)) => problems.report(
                    "vrpn_udp_rejected_source",
                    format_args!(
                        "datagram from {from} is not from the server {}",
                        self.server.ip()
                    ),
                ),
                Err(e) if is_transient(&e) => {}
                Err(e) => problems.report("vrpn_udp_error", format_args!("UDP receive: {e}")),
            }
        }
        Ok(VrpnPoll::Idle)
    }
}

// Checked at compile time: the viewer moves the client into its tracking thread.
const _: () = {
    const fn send<T: Send>() {}
    send::<VrpnSource>();
};

fn now_stamp() -> VrpnTime {
    let d = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap_or_default();
    VrpnTime::new(
        d.as_secs().min(u64::from(u32::MAX)) as u32,
        d.subsec_micros(),
    )
}

fn is_transient(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
    )
}

/// A short write on a non-blocking socket (the 40-byte UDP description right after the
/// cookie exchange: the send buffer is empty, so it goes at once; the loop is for form).
fn write_all_nonblocking(tcp: &mut TcpStream, mut data: &[u8]) -> io::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(1);
    while !data.is_empty() {
        match tcp.write(data) {
            Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
            Ok(n) => data = &data[n..],
            Err(e) if is_transient(&e) && Instant::now() < deadline => std::thread::yield_now(),
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

fn bind_udp(addr: SocketAddr, recv_buffer: usize) -> io::Result<UdpSocket> {
    let socket = Socket::new(
        Domain::for_address(addr),
        Type::DGRAM,
        Some(SockProtocol::UDP),
    )?;
    socket.set_recv_buffer_size(recv_buffer)?;
    socket.bind(&addr.into())?;
    Ok(socket.into())
}

enum Sock<'a> {
    Tcp(&'a TcpStream),
    Udp(&'a UdpSocket),
    Listener(&'a TcpListener),
}

/// Waits until one of `socks` may be readable or `timeout` passed (poll(2); the sockets are
/// non-blocking, so a spurious wake-up costs one `WouldBlock`).
#[cfg(unix)]
fn wait_readable(socks: &[Sock<'_>], timeout: Duration) -> io::Result<()> {
    use std::os::fd::AsRawFd;
    let mut fds: Vec<libc::pollfd> = socks
        .iter()
        .map(|s| libc::pollfd {
            fd: match s {
                Sock::Tcp(t) => t.as_raw_fd(),
                Sock::Udp(u) => u.as_raw_fd(),
                Sock::Listener(l) => l.as_raw_fd(),
            },
            events: libc::POLLIN,
            revents: 0,
        })
        .collect();
    let ms = timeout.as_millis().min(i32::MAX as u128) as libc::c_int;
    // SAFETY: `fds` is a valid, initialised array of `fds.len()` pollfd structs that lives
    // across the call, and every descriptor is owned by a socket borrowed for this call.
    let r = unsafe { libc::poll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, ms) };
    if r < 0 {
        let e = io::Error::last_os_error();
        if e.kind() != io::ErrorKind::Interrupted {
            return Err(e);
        }
    }
    Ok(())
}

/// Without poll(2): a short sleep, then the non-blocking reads look (at most 1 ms late).
#[cfg(not(unix))]
fn wait_readable(_socks: &[Sock<'_>], timeout: Duration) -> io::Result<()> {
    std::thread::sleep(timeout.min(Duration::from_millis(1)));
    Ok(())
}

/// Receives until `stop` is set or the session ends: every read goes through `pipeline`
/// (its VRPN decoder, then the interaction), `on_read` gets each read's events and ROI
/// changes, and the latest ROI is published in `live` (latest-state semantics, as for the UDP
/// listeners: nothing queues between network and ROI). Idle polls let the decoder lose
/// sensors of a silent server; a stream the decoder finds broken is dropped and reconnected.
pub fn run_live(
    source: &mut VrpnSource,
    pipeline: &mut Pipeline,
    surface: &dyn RaySurface,
    stop: &AtomicBool,
    live: &Live,
    mut on_read: impl FnMut(&[TrackingEvent], &[RoiChange]),
) -> io::Result<()> {
    let start = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        let problems_before = pipeline.ingest.problems.total();
        let polled = source.poll(&mut pipeline.ingest.problems)?;
        let t = start.elapsed().as_secs_f64();
        let (events, changes, read) = match polled.datagram() {
            Some((protocol, bytes)) => {
                let (e, c) = pipeline.datagram(protocol, bytes, t, surface);
                (e, c, 1)
            }
            None if polled == VrpnPoll::Ended => break,
            None => {
                let (e, c) = pipeline.idle(t, surface);
                (e, c, 0)
            }
        };
        on_read(events, changes);
        let latest = changes.last().map(|c| c.roi.clone());
        let n_changes = changes.len() as u64;
        let problems = (pipeline.ingest.problems.total() != problems_before)
            .then_some(&pipeline.ingest.problems);
        live.publish(read, latest, n_changes, problems)?;
        if pipeline.ingest.take_vrpn_reconnect() {
            source.drop_connection();
        }
    }
    Ok(())
}

/// Records every read into a replay until `stop` is set, `max_duration` has passed or the
/// session ends (with [`VrpnClientConfig::reconnect`] off: when the server closes). Each read
/// is one `vrpn_tcp_hex` / `vrpn_udp_hex` line with its receive time; the end of a connection
/// is an empty `vrpn_tcp_hex`. The reads also go through `ingest` (problems are counted there,
/// and a broken stream is dropped as in [`run_live`]); its events are not kept. Returns the
/// number of reads written.
pub fn record<W: io::Write>(
    source: &mut VrpnSource,
    writer: &mut ReplayWriter<W>,
    ingest: &mut Ingest,
    stop: &AtomicBool,
    max_duration: Option<Duration>,
) -> io::Result<u64> {
    let start = Instant::now();
    let mut last_flush = start;
    let mut n = 0u64;
    while !stop.load(Ordering::Relaxed) && max_duration.is_none_or(|d| start.elapsed() < d) {
        let polled = source.poll(&mut ingest.problems)?;
        let t = start.elapsed().as_secs_f64();
        match polled.datagram() {
            Some((protocol, bytes)) => {
                writer.datagram(t, protocol, bytes)?;
                let _ = ingest.datagram(protocol, bytes, t);
                n += 1;
            }
            None if polled == VrpnPoll::Ended => break,
            None => {}
        }
        // Under a steady stream as when the line is quiet: a killed recorder keeps everything
        // up to the last flush.
        if last_flush.elapsed() >= super::udp::FLUSH_INTERVAL {
            writer.flush()?;
            last_flush = Instant::now();
        }
        if ingest.take_vrpn_reconnect() {
            source.drop_connection();
        }
    }
    writer.flush()?;
    Ok(n)
}
