fn main() {
    let path = std::env::args().nth(1).unwrap();
    let src = std::fs::read(&path).unwrap();
    for it in kerf_gcode::Interpreter::new(&src[..], kerf_gcode::Dialect::LinuxCnc, kerf_gcode::Settings::default()) {
        println!("{it:?}");
    }
}
