// A handler names the exception it handles as a Rust type: a name declared nowhere (here a typo,
// in a macro that declares no exception for the front end to check against) is a compile error,
// not a handler that never fires (issue 12, point 3).
mod faults {
    tdl::tdl! {
        pub exception TerrainFault;
    }
}
use faults::*;

tdl::tdl! {
    handler recover() handles TerainFault {
        let _ = 1;
    }
    command step() { fail TerrainFault; }
}

fn main() {}
