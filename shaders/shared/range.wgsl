// The contacts of one colour: `count` entries of the colour order from `start`.
struct Range {
    start: u32,
    count: u32,
}
