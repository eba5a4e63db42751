# Writes a LAZ (point format 6, or the one given) of 1000 points whose variable-size chunk table
# ends with an empty chunk, as laz-rs writes one (compress_chunks, then done), and which laspy
# reads. The point-wise compressor of formats 0 to 5 gives that chunk a few bytes, the layered
# one of formats 6 to 10 none.
# Usage: empty_chunk.py OUT.laz [POINTS] [FORMAT]
import io, struct, sys

import laspy, lazrs, numpy as np

out = sys.argv[1]
n = int(sys.argv[2]) if len(sys.argv) > 2 else 1000
fmt = int(sys.argv[3]) if len(sys.argv) > 3 else 6
rng = np.random.default_rng(0)
header = laspy.LasHeader(point_format=fmt, version="1.4" if fmt > 5 else "1.2")
header.scales = np.array([0.001] * 3)
header.offsets = np.zeros(3)
las = laspy.LasData(header)
las.x, las.y, las.z = rng.uniform(0, 10, n), rng.uniform(0, 10, n), rng.uniform(0, 1, n)
plain = io.BytesIO()
las.write(plain, do_compress=False)
raw = bytearray(plain.getvalue())
records = las.points.array.tobytes()
size = len(records) // n
point_data = struct.unpack_from("<I", raw, 96)[0]
# A laszip VLR for variable-size chunks, and the compressed bit set in the point format.
vlr = lazrs.LazVlr.new_for_compression(fmt, 0, True)
data = bytes(vlr.record_data())
vlr_header = struct.pack("<H16sHH32s", 0, b"laszip encoded", 22204, len(data), b"laz")
head = bytearray(raw[:point_data]) + vlr_header + data
struct.pack_into("<I", head, 96, len(head))
struct.pack_into("<I", head, 100, struct.unpack_from("<I", head, 100)[0] + 1)
head[104] |= 0x80
out_bytes = io.BytesIO()
out_bytes.write(bytes(head))
compressor = lazrs.LasZipCompressor(out_bytes, vlr)
cut = min(400, n) * size
compressor.compress_chunks([records[:cut]] + ([records[cut:]] if len(records) > cut else []))
compressor.done()
open(out, "wb").write(out_bytes.getvalue())
assert len(laspy.read(out).points) == n
