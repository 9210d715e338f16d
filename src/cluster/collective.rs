//! The collectives every rank calls in step (DESIGN.md §12): rank 0's data down a binomial
//! tree, every rank's data to rank 0, an all-to-all whole or in two halves whose messages travel
//! while the rank works on — each round over the transport ([`super::exchange::Exchange`]) with
//! a deadline.

use std::time::{Duration, Instant};

use super::exchange::{Exchange, ExchangeError, Lane, Traffic};

/// A rank's handle on the job: the transport, and the deadline rule for every wait.
///
/// A wait may last the timeout plus twice the time this rank spent on its own since its last
/// round (a peer doing the same step may take three times as long as this rank did), doubled
/// on ranks other than 0 so that rank 0, which holds the user's terminal, is the one that
/// reports a rank that stopped answering.
pub struct Cluster {
    x: Box<dyn Exchange>,
    timeout: Duration,
    last: Instant,
}

impl Cluster {
    #[must_use]
    pub fn new(x: Box<dyn Exchange>, timeout: Duration) -> Self {
        Self {
            x,
            timeout,
            last: Instant::now(),
        }
    }

    #[must_use]
    pub fn rank(&self) -> usize {
        self.x.rank()
    }

    #[must_use]
    pub fn ranks(&self) -> usize {
        self.x.ranks()
    }

    #[must_use]
    pub fn is_root(&self) -> bool {
        self.rank() == 0
    }

    /// What this rank has exchanged so far.
    #[must_use]
    pub fn traffic(&self) -> Traffic {
        self.x.traffic()
    }

    /// Ends the whole job now (after an error this rank printed).
    pub fn abort(&self, code: i32) -> ! {
        self.x.abort(code)
    }

    fn wait(&self) -> Duration {
        let local = self.last.elapsed();
        if self.is_root() {
            self.timeout + 2 * local
        } else {
            2 * self.timeout + 3 * local
        }
    }

    fn round(
        &mut self,
        sends: Vec<(usize, Vec<u8>)>,
        from: &[usize],
        what: &str,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        let wait = self.wait();
        self.round_within(sends, from, what, wait)
    }

    fn round_within(
        &mut self,
        sends: Vec<(usize, Vec<u8>)>,
        from: &[usize],
        what: &str,
        wait: Duration,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        let got = self.x.round(sends, from, what, wait);
        self.last = Instant::now();
        got
    }

    /// Rank 0's `data` on every rank (other ranks' `data` is ignored), down a binomial tree as
    /// MPI_Bcast sends it: rank r receives from r with its lowest set bit cleared and passes the
    /// data on to r + 2^k for each 2^k below that bit, so no rank sends more than ⌈log₂ N⌉
    /// copies (a DGI of 295 MB to 34 ranks: 6 copies from rank 0 instead of 34).
    pub fn broadcast(&mut self, what: &str, data: Vec<u8>) -> Result<Vec<u8>, ExchangeError> {
        let wait = self.wait();
        self.broadcast_within(what, data, wait)
    }

    /// [`Self::broadcast`] where the other ranks wait for rank 0 as long as it takes (a day):
    /// the viewer's next step, which comes when its user acts or its window draws again, and
    /// not at all while the window is minimised. A rank 0 that dies still ends the job (mpirun
    /// ends every rank), and rank 0's own waits keep their deadlines.
    pub fn broadcast_patiently(
        &mut self,
        what: &str,
        data: Vec<u8>,
    ) -> Result<Vec<u8>, ExchangeError> {
        self.broadcast_within(what, data, Duration::from_secs(24 * 3600))
    }

    fn broadcast_within(
        &mut self,
        what: &str,
        data: Vec<u8>,
        wait: Duration,
    ) -> Result<Vec<u8>, ExchangeError> {
        let (me, n) = (self.rank(), self.ranks());
        let (parent, children) = binomial_tree(me, n);
        let data = match parent {
            Some(p) => self.round_within(vec![], &[p], what, wait)?.remove(0),
            None => data,
        };
        if !children.is_empty() {
            let sends = children.into_iter().map(|c| (c, data.clone())).collect();
            self.round(sends, &[], what)?;
        }
        Ok(data)
    }

    /// Every rank's `data` on rank 0, by rank (`None` on the other ranks).
    pub fn gather(
        &mut self,
        what: &str,
        data: Vec<u8>,
    ) -> Result<Option<Vec<Vec<u8>>>, ExchangeError> {
        let n = self.ranks();
        if self.is_root() {
            let from: Vec<usize> = (1..n).collect();
            let mut all = vec![data];
            all.extend(self.round(vec![], &from, what)?);
            Ok(Some(all))
        } else {
            self.round(vec![(0, data)], &[], what)?;
            Ok(None)
        }
    }

    /// `parts[r]` to rank `r`; returns what each rank sent this one (its own part at its own
    /// index).
    pub fn all_to_all(
        &mut self,
        what: &str,
        parts: Vec<Vec<u8>>,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        let (own, sends) = self.split_parts(parts);
        let mut got = self.round(sends, &self.others(), what)?;
        got.insert(self.rank(), own);
        Ok(got)
    }

    /// `parts` (one per rank) as this rank's own and the sends to the others.
    fn split_parts(&self, mut parts: Vec<Vec<u8>>) -> (Vec<u8>, Vec<(usize, Vec<u8>)>) {
        let me = self.rank();
        assert_eq!(parts.len(), self.ranks(), "one part per rank");
        let own = std::mem::take(&mut parts[me]);
        let sends = parts
            .into_iter()
            .enumerate()
            .filter(|(r, _)| *r != me)
            .collect();
        (own, sends)
    }

    /// Every rank but this one, ascending.
    fn others(&self) -> Vec<usize> {
        (0..self.ranks()).filter(|&r| r != self.rank()).collect()
    }
}

impl Cluster {
    /// The first half of an all-to-all whose messages travel while this rank works on:
    /// `parts[r]` posted to rank `r` on [`Lane::Later`]; returns this rank's own part, for
    /// [`Self::all_to_all_collect`].
    pub fn all_to_all_post(
        &mut self,
        what: &str,
        parts: Vec<Vec<u8>>,
    ) -> Result<Vec<u8>, ExchangeError> {
        let (own, sends) = self.split_parts(parts);
        self.x.post(sends, Lane::Later, what)?;
        Ok(own)
    }

    /// The second half: what each rank posted this one (`own` at this rank's index), and this
    /// rank's posted sends taken.
    pub fn all_to_all_collect(
        &mut self,
        what: &str,
        own: Vec<u8>,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        let wait = self.wait();
        let mut got = self.x.collect(&self.others(), Lane::Later, what, wait);
        self.last = Instant::now();
        if let Ok(got) = &mut got {
            got.insert(self.rank(), own);
        }
        got
    }
}

/// Rank `me`'s parent (`None` for rank 0) and children, in sending order, in the binomial tree
/// of `n` ranks rooted at 0.
#[must_use]
pub fn binomial_tree(me: usize, n: usize) -> (Option<usize>, Vec<usize>) {
    let low = if me == 0 {
        n.next_power_of_two()
    } else {
        1 << me.trailing_zeros()
    };
    let parent = (me != 0).then(|| me - low);
    let mut children = Vec::new();
    let mut step = low >> 1;
    while step > 0 {
        if me + step < n {
            children.push(me + step);
        }
        step >>= 1;
    }
    (parent, children)
}
