//! The seam between the cluster frame and its transport: a rank sends byte messages to other
//! ranks and receives one message from each rank it expects, with a bound on every wait.
//!
//! [`Exchange`] is that one operation ([`Exchange::round`]), also in two halves: sends posted
//! now ([`Exchange::post`]) and their messages collected later ([`Exchange::collect`]), so that
//! a frame's samples travel while the next frame is traced. The collectives the frame needs
//! (broadcast from rank 0, all-to-all, gather to rank 0) are built on it in [`super::Cluster`].
//! Two backends: [`InProcess`] (N ranks as threads of one process, joined by channels — the unit
//! tests' ranks) and, with the `cluster` feature, MPI (`super::mpi`). Messages between a pair of
//! ranks on one [`Lane`] arrive in the order they were sent (MPI's non-overtaking rule for one
//! tag; a channel's order), and every rank runs the same sequence of rounds, so no sequence
//! numbers are needed; the two lanes keep a message posted for later from being taken by a
//! round in between.

use std::collections::VecDeque;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::time::{Duration, Instant};

/// Why a round failed. Every variant names the rank at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExchangeError {
    #[error("rank {rank} did not answer within {seconds:.1} s ({what}): it stopped or hangs")]
    Timeout {
        rank: usize,
        seconds: f64,
        what: String,
    },
    #[error("rank {rank} is gone ({what}): it ended or failed (its own message says why)")]
    Gone { rank: usize, what: String },
    #[error("rank {rank} sent {got} bytes for {what}; {expected} were expected")]
    Length {
        rank: usize,
        what: String,
        got: usize,
        expected: usize,
    },
    #[error("rank {rank}: {what}: {reason}")]
    Malformed {
        rank: usize,
        what: String,
        reason: String,
    },
    #[error("MPI: {0}")]
    Mpi(String),
}

impl ExchangeError {
    /// Rank `rank` did not answer within `wait` (`what`: the messages waited for).
    pub(crate) fn timeout(rank: usize, wait: Duration, what: &str) -> Self {
        Self::Timeout {
            rank,
            seconds: wait.as_secs_f64(),
            what: what.to_owned(),
        }
    }
}

/// Bytes and messages a rank has sent and received so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Traffic {
    pub bytes_sent: u64,
    pub bytes_received: u64,
    pub messages_sent: u64,
    pub messages_received: u64,
}

impl Traffic {
    /// What was exchanged since `earlier`.
    #[must_use]
    pub fn since(&self, earlier: &Self) -> Self {
        Self {
            bytes_sent: self.bytes_sent - earlier.bytes_sent,
            bytes_received: self.bytes_received - earlier.bytes_received,
            messages_sent: self.messages_sent - earlier.messages_sent,
            messages_received: self.messages_received - earlier.messages_received,
        }
    }

    pub(crate) fn count_sent(&mut self, sends: &[(usize, Vec<u8>)]) {
        self.bytes_sent += sends.iter().map(|(_, b)| b.len() as u64).sum::<u64>();
        self.messages_sent += sends.len() as u64;
    }

    pub(crate) fn count_received(&mut self, received: &[Vec<u8>]) {
        self.bytes_received += received.iter().map(|b| b.len() as u64).sum::<u64>();
        self.messages_received += received.len() as u64;
    }
}

/// The two sequences of messages between a pair of ranks: a receive takes the next message of
/// its own lane, so a message posted on one is never taken by a receive on the other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lane {
    /// Rounds sent and received in one step.
    Now = 0,
    /// Messages posted in one frame and collected in the next: a frame's samples, in flight
    /// while the next frame is traced.
    Later = 1,
}

/// A rank's link to the others.
pub trait Exchange {
    /// This rank, `0..ranks()`.
    fn rank(&self) -> usize;
    /// How many ranks the job has.
    fn ranks(&self) -> usize;
    /// Starts sending each `(rank, bytes)` of `sends` (never to itself) on `lane`, without
    /// waiting for the receivers. `what` names the messages in an error.
    fn post(
        &mut self,
        sends: Vec<(usize, Vec<u8>)>,
        lane: Lane,
        what: &str,
    ) -> Result<(), ExchangeError>;
    /// Receives the next message on `lane` from each rank of `from`, in that order, waiting at
    /// most `wait` for each; then waits (as long) for this rank's sends posted on `lane` to
    /// be taken. `what` names the messages in an error.
    fn collect(
        &mut self,
        from: &[usize],
        lane: Lane,
        what: &str,
        wait: Duration,
    ) -> Result<Vec<Vec<u8>>, ExchangeError>;
    /// One round: [`Self::post`] then [`Self::collect`] on [`Lane::Now`].
    fn round(
        &mut self,
        sends: Vec<(usize, Vec<u8>)>,
        from: &[usize],
        what: &str,
        wait: Duration,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        self.post(sends, Lane::Now, what)?;
        self.collect(from, Lane::Now, what, wait)
    }
    /// What this rank has exchanged so far.
    fn traffic(&self) -> Traffic;
    /// Ends the whole job at once (MPI_Abort) after an error this rank has printed: the other
    /// ranks would otherwise wait for it until their deadline.
    fn abort(&self, code: i32) -> !;
}

/// A message between in-process ranks: its lane and its bytes.
type Message = (Lane, Vec<u8>);

/// One rank of an in-process job: N ranks as threads, one channel per ordered pair of ranks
/// carrying both lanes, each message with its lane.
pub struct InProcess {
    rank: usize,
    /// `to[r]`: the channel to rank `r` (`None` for this rank itself).
    to: Vec<Option<Sender<Message>>>,
    /// `from[r]`: the channel from rank `r`.
    from: Vec<Option<Receiver<Message>>>,
    /// `held[r][lane]`: messages from rank `r` that arrived while a receive waited for the
    /// other lane, oldest first.
    held: Vec<[VecDeque<Vec<u8>>; 2]>,
    traffic: Traffic,
}

impl InProcess {
    /// The `ranks` ends of a new in-process job, rank 0 first.
    #[must_use]
    pub fn job(ranks: usize) -> Vec<Self> {
        let mut ends: Vec<Self> = (0..ranks)
            .map(|rank| Self {
                rank,
                to: (0..ranks).map(|_| None).collect(),
                from: (0..ranks).map(|_| None).collect(),
                held: (0..ranks).map(|_| Default::default()).collect(),
                traffic: Traffic::default(),
            })
            .collect();
        for a in 0..ranks {
            for b in 0..ranks {
                if a != b {
                    let (tx, rx) = channel();
                    ends[a].to[b] = Some(tx);
                    ends[b].from[a] = Some(rx);
                }
            }
        }
        ends
    }
}

impl Exchange for InProcess {
    fn rank(&self) -> usize {
        self.rank
    }

    fn ranks(&self) -> usize {
        self.to.len()
    }

    fn post(
        &mut self,
        sends: Vec<(usize, Vec<u8>)>,
        lane: Lane,
        _what: &str,
    ) -> Result<(), ExchangeError> {
        self.traffic.count_sent(&sends);
        for (dest, bytes) in sends {
            let tx = self.to[dest]
                .as_ref()
                .expect("a round sends to other ranks only");
            // A message to a rank that is gone is lost, as MPI's non-blocking send does not
            // fail either: this rank learns of it when it next waits for that rank, as every
            // rank that waits for it does (so that rank 0, not the first rank to post, names
            // it).
            let _ = tx.send((lane, bytes));
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
        let mut got = Vec::with_capacity(from.len());
        for &src in from {
            if let Some(bytes) = self.held[src][lane as usize].pop_front() {
                got.push(bytes);
                continue;
            }
            let rx = self.from[src]
                .as_ref()
                .expect("a round receives from other ranks only");
            let deadline = Instant::now() + wait;
            loop {
                let left = deadline.saturating_duration_since(Instant::now());
                match rx.recv_timeout(left) {
                    Ok((l, bytes)) if l == lane => {
                        got.push(bytes);
                        break;
                    }
                    Ok((other, bytes)) => self.held[src][other as usize].push_back(bytes),
                    Err(RecvTimeoutError::Timeout) => {
                        return Err(ExchangeError::timeout(src, wait, what));
                    }
                    Err(RecvTimeoutError::Disconnected) => {
                        return Err(ExchangeError::Gone {
                            rank: src,
                            what: what.to_owned(),
                        });
                    }
                }
            }
        }
        self.traffic.count_received(&got);
        Ok(got)
    }

    fn traffic(&self) -> Traffic {
        self.traffic
    }

    fn abort(&self, code: i32) -> ! {
        panic!("rank {} ended the in-process job (code {code})", self.rank)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_arrive_in_order_and_are_counted() {
        let mut ends = InProcess::job(2);
        let mut b = ends.pop().unwrap();
        let mut a = ends.pop().unwrap();
        let w = Duration::from_secs(5);
        a.round(vec![(1, vec![1, 2]), (1, vec![3])], &[], "t", w)
            .unwrap();
        let got = b.round(vec![], &[0, 0], "t", w).unwrap();
        assert_eq!(got, vec![vec![1, 2], vec![3]]);
        assert_eq!(a.traffic().bytes_sent, 3);
        assert_eq!(b.traffic().bytes_received, 3);
        assert_eq!(b.traffic().messages_received, 2);
    }

    /// A message posted for later waits on its lane while rounds in between take theirs, in
    /// both orders of arrival, and each lane keeps its own order.
    #[test]
    fn the_later_lane_is_not_taken_by_rounds_in_between() {
        let mut ends = InProcess::job(2);
        let mut b = ends.pop().unwrap();
        let mut a = ends.pop().unwrap();
        let w = Duration::from_secs(5);
        a.post(vec![(1, vec![10])], Lane::Later, "samples 0")
            .unwrap();
        a.post(vec![(1, vec![11])], Lane::Later, "samples 1")
            .unwrap();
        a.round(vec![(1, vec![1])], &[], "counts", w).unwrap();
        a.round(vec![(1, vec![2])], &[], "counts", w).unwrap();
        assert_eq!(b.round(vec![], &[0], "counts", w).unwrap(), vec![vec![1]]);
        assert_eq!(
            b.collect(&[0], Lane::Later, "samples 0", w).unwrap(),
            vec![vec![10]]
        );
        assert_eq!(b.round(vec![], &[0], "counts", w).unwrap(), vec![vec![2]]);
        assert_eq!(
            b.collect(&[0], Lane::Later, "samples 1", w).unwrap(),
            vec![vec![11]]
        );
        assert_eq!(a.traffic().messages_sent, 4);
        assert_eq!(b.traffic().messages_received, 4);
        // Nothing left on either lane.
        let e = b
            .collect(&[0], Lane::Later, "samples 2", Duration::from_millis(20))
            .unwrap_err();
        assert!(matches!(e, ExchangeError::Timeout { rank: 0, .. }), "{e:?}");
    }

    #[test]
    fn a_silent_rank_times_out_and_a_dropped_one_is_gone_both_named() {
        let mut ends = InProcess::job(3);
        let c = ends.pop().unwrap();
        let _b = ends.pop().unwrap();
        let mut a = ends.pop().unwrap();
        let e = a
            .round(vec![], &[1], "samples", Duration::from_millis(20))
            .unwrap_err();
        assert!(matches!(e, ExchangeError::Timeout { rank: 1, .. }), "{e:?}");
        assert!(e.to_string().contains("rank 1"), "{e}");
        drop(c);
        let e = a
            .round(vec![], &[2], "samples", Duration::from_secs(5))
            .unwrap_err();
        assert!(matches!(e, ExchangeError::Gone { rank: 2, .. }), "{e:?}");
    }
}
