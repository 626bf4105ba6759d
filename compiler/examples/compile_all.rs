//! Compiles every .psg under the given folders and prints diagnostics and sizes (a debugging
//! aid for the compiler without the CLI; `psc compile` is the user-facing command).
fn main() {
    let mut files = Vec::new();
    for arg in std::env::args().skip(1) {
        let p = std::path::PathBuf::from(&arg);
        if p.is_dir() {
            let mut stack = vec![p];
            while let Some(d) = stack.pop() {
                for e in std::fs::read_dir(&d).unwrap() {
                    let path = e.unwrap().path();
                    if path.is_dir() {
                        stack.push(path);
                    } else if path.extension().is_some_and(|x| x == "psg") {
                        files.push(path);
                    }
                }
            }
        } else {
            files.push(p);
        }
    }
    files.sort();
    let t = std::time::Instant::now();
    let out = psc_compiler::compile_files(&files, &Default::default());
    eprint!("{}", out.render_diagnostics());
    for g in &out.graphs {
        println!("{:<28} {:>6} ops  {:>3} slots", g.info.name, g.forward.op_count(), g.info.num_slots());
    }
    println!("{} graphs from {} files in {:?}", out.graphs.len(), files.len(), t.elapsed());
}
