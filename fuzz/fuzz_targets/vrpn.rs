//! VRPN reads: never panic, and whatever decodes yields valid events only.
//!
//! Input: byte 0 chooses whether a valid server preamble (cookie and vrpn_server's
//! descriptions, ids as in `tests/data/vrpn/`) comes first; then chunks, each a control byte
//! (bit 7: UDP, else TCP; bits 0–6: length, 0 on TCP = the connection ends, 127: add the next
//! byte) and its bytes. So the fuzzer chooses how the stream is cut into reads and datagrams.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raygun::tracking::dtrack::TimeSource;
use raygun::tracking::problems::ProblemLog;
use raygun::tracking::vrpn::wire::encode;
use raygun::tracking::vrpn::{Channel, VrpnConfig, VrpnDecoder};

fn preamble() -> Vec<u8> {
    let mut b = encode::cookie().to_vec();
    encode::sender_description(&mut b, 0, 0, "VRPN Control");
    encode::sender_description(&mut b, 1, 1, "DTrack");
    for (id, name) in [
        (4, "vrpn_Tracker Pos_Quat"),
        (5, "vrpn_Tracker Velocity"),
        (18, "vrpn_Button Change"),
        (19, "vrpn_Button States"),
        (22, "vrpn_Analog Channel"),
    ] {
        encode::type_description(&mut b, 2, id, name);
    }
    b
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, mut rest)) = data.split_first() else {
        return;
    };
    let mut d = VrpnDecoder::new("DTrack", VrpnConfig::default(), TimeSource::Tracker).unwrap();
    let mut out = Vec::new();
    let mut problems = ProblemLog::quiet();
    if mode & 1 == 1 {
        d.decode(Channel::Tcp, &preamble(), 0.0, &mut out, &mut problems);
    }
    let mut t = 0.0;
    while let Some((&c, mut tail)) = rest.split_first() {
        let mut n = usize::from(c & 0x7f);
        if n == 0x7f
            && let Some((&more, t)) = tail.split_first()
        {
            n += usize::from(more);
            tail = t;
        }
        let n = n.min(tail.len());
        let (chunk, after) = tail.split_at(n);
        rest = after;
        let channel = if c & 0x80 != 0 { Channel::Udp } else { Channel::Tcp };
        t += 0.01;
        d.decode(channel, chunk, t, &mut out, &mut problems);
        assert!(out.iter().all(|e| e.is_valid()), "{out:?}");
        out.clear();
        d.idle(t + 1.0, &mut out);
        assert!(out.iter().all(|e| e.is_valid()));
        out.clear();
    }
});
