// A thread's walk over the pixels of a box in one loop, row by row. A SIMD group of threads
// runs until its longest walk ends; nested loops over rows and columns ran as many rows as any
// of its threads had, each as long as the widest row among them.

// Pixels of the box (x0, y0, x1, y1, inclusive); 0 where it is empty.
fn box_pixels(b: vec4<u32>) -> u32 {
    if b.z < b.x || b.w < b.y {
        return 0u;
    }
    return (b.z - b.x + 1u) * (b.w - b.y + 1u);
}

// The pixel after `at` in the box.
fn box_next(b: vec4<u32>, at: vec2<u32>) -> vec2<u32> {
    return select(vec2<u32>(b.x, at.y + 1u), vec2<u32>(at.x + 1u, at.y), at.x < b.z);
}
