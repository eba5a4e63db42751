// The per-pixel sums of the blend pass.

// Fixed-point weight of a surfel's centre: rim weights keep about 8 bits, and a pixel may
// sum a million full weights before a word overflows.
const WEIGHT_ONE: f32 = 4096.0;
// Words per pixel: w, w*r, w*g, w*b, w*nx, w*ny, w*nz, w*layer, and the w of back faces.
const SUM_WORDS: u32 = 9u;
