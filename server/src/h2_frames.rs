//! Which bytes of an HTTP/2 connection are progress. From the server: an answer going out, as
//! `MIN_DATA_PROGRESS` bytes of bodies (DATA), or the end of a stream (DATA or HEADERS that end
//! it: a whole answer, a 304, 404 or 416 included). From the client: a request, once its header
//! block has come whole, which `IdleTimeout` counts only while no answer has moved since the
//! last it counted, so that a request that comes just before the limit has its time.
//! PING, SETTINGS and WINDOW_UPDATE keep a connection open without moving anything, and a
//! client that holds its windows shut keeps its answers from moving: counted as progress,
//! requests every 25 s held such a connection, and the answers buffered on it, for good (512
//! connections held 4.2 GB and every slot), and so would a window opened a byte at a time for
//! a one-byte DATA frame.

const DATA: u8 = 0x0;
const HEADERS: u8 = 0x1;
const CONTINUATION: u8 = 0x9;
const END_STREAM: u8 = 0x1;
const END_HEADERS: u8 = 0x4;

/// Bytes of answers' bodies that make progress: 16 KiB within the idle limit (60 s by
/// default), under 300 bytes a second, is a client that is not reading.
pub const MIN_DATA_PROGRESS: usize = 16 << 10;

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
    /// The current frame is DATA (server): its payload counts towards `MIN_DATA_PROGRESS`.
    data: bool,
    /// The current frame is progress once its last byte has passed: it ends a stream (server)
    /// or a request's header block (client).
    ends: bool,
    /// DATA payload bytes since the last progress.
    sent: usize,
}

impl FrameScan {
    pub fn new(side: Side) -> Self {
        FrameScan {
            side,
            head: [0; 9],
            have: 0,
            left: 0,
            data: false,
            ends: false,
            sent: 0,
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
                if self.data {
                    self.sent += n;
                }
            } else {
                let n = (self.head.len() - self.have).min(bytes.len());
                self.head[self.have..self.have + n].copy_from_slice(&bytes[..n]);
                self.have += n;
                bytes = &bytes[n..];
                if self.have < self.head.len() {
                    continue;
                }
                self.have = 0;
                let [a, b, c, kind, flags, ..] = self.head;
                self.left = u32::from_be_bytes([0, a, b, c]) as usize;
                (self.data, self.ends) = match self.side {
                    Side::Server => (
                        kind == DATA,
                        matches!(kind, DATA | HEADERS) && flags & END_STREAM != 0,
                    ),
                    Side::Client => (
                        false,
                        matches!(kind, HEADERS | CONTINUATION) && flags & END_HEADERS != 0,
                    ),
                };
            }
            if self.left == 0 && self.ends {
                self.ends = false;
                moved = true;
            }
            if self.sent >= MIN_DATA_PROGRESS {
                moved = true;
            }
            if moved {
                self.sent = 0;
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

    /// The indices of the pieces of `stream`, cut every `cut` bytes, that made progress.
    fn progress(side: Side, stream: &[u8], cut: usize) -> Vec<usize> {
        let mut scan = FrameScan::new(side);
        (0..)
            .zip(stream.chunks(cut))
            .filter(|(_, piece)| scan.feed(piece))
            .map(|(i, _)| i)
            .collect()
    }

    #[test]
    fn an_answer_is_progress_as_it_ends_or_its_bodies_add_up() {
        let ping = frame(0x6, &[7; 8]);
        let settings = frame(0x4, &[0, 4, 0, 0, 0, 0]);
        // Headers whose body waits on the client's window: nothing moved yet.
        let opening = frame(HEADERS, &[0x88; 20]);
        let small = frame(DATA, &[1; 300]);
        let last = frame_with(DATA, END_STREAM, &[1; 300]);
        let stream: Vec<u8> = [ping.clone(), settings, opening, small.clone(), ping].concat();
        for cut in [1, 2, 5, 9, 17, 64, stream.len()] {
            assert_eq!(progress(Side::Server, &stream, cut), Vec::<usize>::new());
            // The stream's end: the piece with its last byte.
            let ended = [stream.clone(), last.clone()].concat();
            assert_eq!(
                progress(Side::Server, &ended, cut),
                vec![(ended.len() - 1) / cut],
                "pieces of {cut} bytes"
            );
        }
        // Small DATA frames count once they add up to MIN_DATA_PROGRESS bytes, not before.
        let frames = MIN_DATA_PROGRESS / 300 + 1;
        let many: Vec<u8> = std::iter::repeat_n(small, frames).flatten().collect();
        assert_eq!(progress(Side::Server, &many, many.len()).len(), 1);
        assert_eq!(
            progress(Side::Server, &many[..many.len() - 309], many.len()).len(),
            0
        );
        // A whole answer without a body, a 304 or a 404; a stream's refusal is none.
        assert!(FrameScan::new(Side::Server).feed(&frame_with(HEADERS, END_STREAM, &[0x89; 9])));
        assert!(!FrameScan::new(Side::Server).feed(&frame(0x3, &[0, 0, 0, 7])));
        // From the client, DATA is no progress (a GET has no body to read).
        assert!(!FrameScan::new(Side::Client).feed(&small_data()));
    }

    fn small_data() -> Vec<u8> {
        frame_with(DATA, END_STREAM, &[1; 30])
    }

    #[test]
    fn a_request_is_progress_once_its_header_block_has_ended_and_arrived() {
        let whole = frame_with(HEADERS, END_HEADERS | END_STREAM, &[0x82; 40]);
        assert!(FrameScan::new(Side::Client).feed(&whole));
        // Trickled: only the piece with its last byte.
        assert_eq!(progress(Side::Client, &whole, 1), vec![whole.len() - 1]);
        // A block that goes on in CONTINUATION frames: only the one that ends it.
        let mut scan = FrameScan::new(Side::Client);
        assert!(!scan.feed(&frame(HEADERS, &[0x82; 10])));
        assert!(!scan.feed(&frame(CONTINUATION, &[0x82; 10])));
        assert!(scan.feed(&frame_with(CONTINUATION, END_HEADERS, &[0x82; 10])));
    }
}
