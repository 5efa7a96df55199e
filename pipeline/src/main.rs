mod gen;
fn main() {}
