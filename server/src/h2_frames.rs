//! Which bytes of an HTTP/2 connection are progress: a whole request from the client (the
//! frame that ends its header block, HEADERS or CONTINUATION with END_HEADERS, once all of it
//! came: a block trickled a byte at a time is none), and any byte of an answer from the server
//! (HEADERS, CONTINUATION, DATA). PING, SETTINGS, WINDOW_UPDATE and the rest keep a connection
//! open without moving anything: counted as progress, a client sending a PING a minute, or
//! holding its streams' windows shut, held the connection and the answers buffered on it for
//! good.

const DATA: u8 = 0x0;
const HEADERS: u8 = 0x1;
const CONTINUATION: u8 = 0x9;
const END_HEADERS: u8 = 0x4;

/// Which side's frames a scan follows.
#[derive(Clone, Copy, PartialEq)]
pub enum Side {
    Client,
    Server,
}

/// Follows the frames of one direction, given its bytes in order, however they are cut.
pub struct FrameScan {
    side: Side,
    head: [u8; 9],
    have: usize,
    /// Payload bytes of the current frame still to come.
    left: usize,
    /// Whether the current frame's bytes are progress (server), or its last byte is (client).
    moving: bool,
}

impl FrameScan {
    pub fn new(side: Side) -> Self {
        FrameScan {
            side,
            head: [0; 9],
            have: 0,
            left: 0,
            moving: false,
        }
    }

    /// Takes the next bytes; whether they made progress.
    pub fn feed(&mut self, mut bytes: &[u8]) -> bool {
        let mut moved = false;
        while !bytes.is_empty() {
            if self.left > 0 {
                let n = self.left.min(bytes.len());
                self.left -= n;
                bytes = &bytes[n..];
                moved |= self.moving && (self.side == Side::Server || self.left == 0);
                continue;
            }
            let n = (self.head.len() - self.have).min(bytes.len());
            self.head[self.have..self.have + n].copy_from_slice(&bytes[..n]);
            self.have += n;
            bytes = &bytes[n..];
            if self.have == self.head.len() {
                self.have = 0;
                let [a, b, c, kind, flags, ..] = self.head;
                self.left = u32::from_be_bytes([0, a, b, c]) as usize;
                self.moving = match self.side {
                    Side::Server => matches!(kind, DATA | HEADERS | CONTINUATION),
                    Side::Client => {
                        matches!(kind, HEADERS | CONTINUATION) && flags & END_HEADERS != 0
                    }
                };
                moved |= self.moving && (self.side == Side::Server || self.left == 0);
            }
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame_with(kind: u8, flags: u8, payload: &[u8]) -> Vec<u8> {
        let len = (payload.len() as u32).to_be_bytes();
        let mut f = vec![len[1], len[2], len[3], kind, flags, 0, 0, 0, 1];
        f.extend_from_slice(payload);
        f
    }

    fn frame(kind: u8, payload: &[u8]) -> Vec<u8> {
        frame_with(kind, 0, payload)
    }

    #[test]
    fn only_requests_and_answers_are_progress_however_the_bytes_are_cut() {
        let ping = frame(0x6, &[7; 8]);
        let settings = frame(0x4, &[0, 4, 0, 0, 0, 0]);
        let data = frame(DATA, &[1; 300]);
        let stream: Vec<u8> = [ping.clone(), settings, data.clone(), ping.clone()].concat();
        let data_at = ping.len() + 15; // after the PING and the SETTINGS
        for cut in [1, 2, 5, 9, 17, 64, stream.len()] {
            let mut scan = FrameScan::new(Side::Server);
            let mut moved_at = Vec::new();
            for (i, piece) in stream.chunks(cut).enumerate() {
                if scan.feed(piece) {
                    moved_at.push(i);
                }
            }
            // The pieces that hold a byte of the DATA frame from its header's last (where its
            // kind is known), and no others.
            let known = data_at + 8;
            let want: Vec<usize> = (0..stream.len().div_ceil(cut))
                .filter(|&i| i * cut < data_at + data.len() && (i + 1) * cut > known)
                .collect();
            assert_eq!(moved_at, want, "pieces of {cut} bytes");
        }
        // From the client, DATA is no progress (a GET has no body to read).
        assert!(!FrameScan::new(Side::Client).feed(&data));
    }

    #[test]
    fn a_request_is_progress_once_its_header_block_has_ended_and_arrived() {
        let whole = frame_with(HEADERS, END_HEADERS, &[0x82; 40]);
        assert!(FrameScan::new(Side::Client).feed(&whole));
        // Trickled: only the piece with its last byte.
        let mut scan = FrameScan::new(Side::Client);
        let moved: Vec<bool> = whole.iter().map(|b| scan.feed(&[*b])).collect();
        assert_eq!(moved.iter().filter(|m| **m).count(), 1);
        assert_eq!(moved.last(), Some(&true));
        // A block that goes on in CONTINUATION frames: only the one that ends it.
        let mut scan = FrameScan::new(Side::Client);
        assert!(!scan.feed(&frame(HEADERS, &[0x82; 10])));
        assert!(!scan.feed(&frame(CONTINUATION, &[0x82; 10])));
        assert!(scan.feed(&frame_with(CONTINUATION, END_HEADERS, &[0x82; 10])));
    }
}
