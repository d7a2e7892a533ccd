// The contacts of one colour: `count` entries of the colour order from `start`. A coloured NLGS
// sweep updates a contact only while its residual in velocity units exceeds `threshold` (the
// work list's sweeps); 0: every contact.
struct Range {
    start: u32,
    count: u32,
    threshold: f32,
}
