//! The `slam2world` command line; see `slam2world --help`.

fn main() {
    slam2world::buffer::bound_arenas();
    std::process::exit(slam2world::cli::main_with_args(std::env::args_os()));
}
