// The counters the pipeline reports: points culled by the reprojected depth, triangles drawn,
// empty pixels inside the silhouette and pixels covered.
const COUNT_CULLED: u32 = 0u;
const COUNT_TRIANGLES: u32 = 1u;
const COUNT_HOLES: u32 = 2u;
const COUNT_COVERED: u32 = 3u;
const COUNT_WORDS: u32 = 4u;
