//! Which bytes of an HTTP/2 connection are progress: an answer's body going out (DATA), or a
//! whole answer without one (HEADERS that end the stream: a 304, 404 or 416). Nothing the
//! client sends is: PING, SETTINGS and WINDOW_UPDATE keep a connection open without moving
//! anything, and so does a request, which the server may only refuse (RST_STREAM, once the
//! connection's streams are all taken) or answer with headers whose body then waits on a
//! window the client holds shut. Counted as progress, a client sending a request every 25 s
//! with its windows shut held its connection, and the answers buffered on it, past the idle
//! limit for good (512 such connections held 4.2 GB and every slot).

const DATA: u8 = 0x0;
const HEADERS: u8 = 0x1;
const END_STREAM: u8 = 0x1;

/// Follows the server's frames, given its bytes in order, however they are cut.
pub struct FrameScan {
    head: [u8; 9],
    have: usize,
    /// Payload bytes of the current frame still to come.
    left: usize,
    /// Whether the current frame's bytes are progress.
    moving: bool,
}

impl FrameScan {
    pub fn new() -> Self {
        FrameScan {
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
                moved |= self.moving;
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
                self.moving = kind == DATA || (kind == HEADERS && flags & END_STREAM != 0);
                moved |= self.moving;
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
    fn only_answers_going_out_are_progress_however_the_bytes_are_cut() {
        let ping = frame(0x6, &[7; 8]);
        let settings = frame(0x4, &[0, 4, 0, 0, 0, 0]);
        let data = frame(DATA, &[1; 300]);
        let stream: Vec<u8> = [ping.clone(), settings, data.clone(), ping.clone()].concat();
        let data_at = ping.len() + 15; // after the PING and the SETTINGS
        for cut in [1, 2, 5, 9, 17, 64, stream.len()] {
            let mut scan = FrameScan::new();
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
    }

    #[test]
    fn headers_are_progress_only_where_they_are_the_whole_answer() {
        // An answer's headers whose body waits on the client's window: nothing moved yet.
        assert!(!FrameScan::new().feed(&frame(HEADERS, &[0x88; 20])));
        // A 304 or a 404: the answer is complete.
        assert!(FrameScan::new().feed(&frame_with(HEADERS, END_STREAM, &[0x89; 20])));
        // A refusal of a stream (RST_STREAM) is none.
        assert!(!FrameScan::new().feed(&frame(0x3, &[0, 0, 0, 7])));
    }
}
