#!/bin/sh
# Builds the seed corpus of every fuzz target from the real test data in ../shared/data (used in
# place, never copied into the repository): LAS/LAZ headers with their VLRs and first records,
# PLY headers with their first vertices, and node payloads and hierarchy pages of a converted
# dataset. Run from the repository root or from fuzz/: sh fuzz/seed.sh
set -eu
cd "$(dirname "$0")"
data=../../shared/data
[ -d "$data" ] || data=../shared/data
mkdir -p corpus/las_open corpus/ply_open corpus/node_decode corpus/page_decode
# Whole small inputs would make each run slow; the first 64 KiB keep the header, every VLR and
# thousands of records (a truncated body is itself a case the reader must refuse cleanly).
for f in autzen_trim.las autzen_trim_pf7.las; do
  head -c 65536 "$data/$f" > "corpus/las_open/$f.head"
done
# A LAZ file is only decodable whole (its chunk table is at the end): keep it whole.
cp "$data/autzen_trim.laz" corpus/las_open/autzen_trim.laz
for f in bunny_bun_zipper.ply bunny_range_scans_merged.ply spot_triangulated.ply; do
  head -c 16384 "$data/$f" > "corpus/ply_open/$f.head"
done
# Node payloads and pages of a real dataset: convert autzen and cut its files into entries.
bin=../target/release/strata
if [ -x "$bin" ]; then
  tmp=$(mktemp -d)
  "$bin" convert "$data/autzen_trim.las" -o "$tmp/ds" --quiet
  # hierarchy.bin: a 32-byte head, then pages; the root page is the first one after it.
  python3 - "$tmp/ds" corpus <<'PY'
import json, struct, sys, zlib
ds, corpus = sys.argv[1], sys.argv[2]
meta = json.load(open(ds + "/metadata.json"))
hier = open(ds + "/hierarchy.bin", "rb").read()
octree = open(ds + "/octree.bin", "rb").read()
h = meta["hierarchy"]
page = hier[h["root_page_offset"]:h["root_page_offset"] + h["root_page_size"]]
# The target's first byte: root level 0, five page levels; its second: format 1.1.
open(corpus + "/page_decode/root", "wb").write(b"\x80\x01" + page)
# Entries of the root page: kind, mask, pad, count, offset, size, crc (24 bytes each); in 1.1
# proxies locate their node's payload too.
body = page[:-4]
entries = struct.unpack_from("<I", body, 0)[0]
stride = 12 + sum({"u8":1,"i8":1,"u16":2,"i16":2,"u32":4,"i32":4,"f32":4,"u64":8,"i64":8,"f64":8}[a["type"]] * a["count"] for a in meta["attributes"])
n = 0
for i in range(4, 4 + 24 * entries, 24):
    kind, mask, _, count, off, size, crc = struct.unpack_from("<BBHIQII", body, i)
    if size > 0 and n < 8:
        payload = octree[off:off + size]
        # The node_decode target reads: count (u32), attribute count, attribute width, payload.
        open(corpus + "/node_decode/node%d" % n, "wb").write(struct.pack("<IBB", count, 0, 0) + payload)
        n += 1
PY
  rm -rf "$tmp"
fi
ls corpus/*
