//! `scripts/rustc-pgo`, the rustc wrapper that builds optimised mavtables with the
//! profile in `pgo/`: run against a stand-in compiler that prints the arguments it got,
//! it must change exactly the optimised builds of the mavtables crate.

use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// A stand-in `rustc` in its own directory, whose LLVM is `llvm` (what `-vV` says) and
/// which prints every other invocation's arguments, one a line.
fn fake_rustc(name: &str, llvm: u32) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("pgo-wrapper-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    let rustc = dir.join("rustc");
    std::fs::write(
        &rustc,
        format!(
            "#!/bin/sh\nif [ \"$1\" = -vV ]; then echo 'rustc 1.0.0'; echo 'LLVM version: {llvm}.1.0'; exit 0; fi\nfor a in \"$@\"; do echo \"$a\"; done\n"
        ),
    )
    .expect("write the stand-in");
    std::fs::set_permissions(&rustc, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    rustc
}

/// The arguments the wrapper handed to `compiler` for `args`.
fn wrapped(compiler: &Path, args: &[&str]) -> Vec<String> {
    let out = Command::new(repo("scripts/rustc-pgo"))
        .arg(compiler)
        .args(args)
        .output()
        .expect("run scripts/rustc-pgo");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(str::to_string)
        .collect()
}

fn optimised(crate_name: &'static str, crate_type: &'static str) -> Vec<&'static str> {
    vec![
        "--crate-name",
        crate_name,
        "--crate-type",
        crate_type,
        "-C",
        "opt-level=3",
        "-C",
        "metadata=0123456789abcdef",
        "-C",
        "extra-filename=-0123456789abcdef",
    ]
}

fn profile_flag() -> String {
    format!("-Cprofile-use={}", repo("pgo/mavtables.profdata").display())
}

/// The LLVM that wrote the committed profile.
fn profile_llvm() -> u32 {
    let text = std::fs::read_to_string(repo("pgo/llvm-major")).expect("pgo/llvm-major");
    text.trim().parse().expect("a major version number")
}

#[test]
fn an_optimised_mavtables_build_gets_the_profile_and_fixed_metadata() {
    assert!(
        repo("pgo/mavtables.profdata").is_file(),
        "the profile is committed"
    );
    let rustc = fake_rustc("optimised", profile_llvm());
    let lib = wrapped(&rustc, &optimised("mavtables", "lib"));
    assert!(
        lib.contains(&"metadata=mavtables-lib".to_string()),
        "{lib:?}"
    );
    assert!(
        !lib.iter()
            .any(|a| a.contains("0123456789abcdef") && a.starts_with("metadata"))
    );
    assert!(lib.contains(&"extra-filename=-0123456789abcdef".to_string()));
    assert_eq!(lib.last(), Some(&profile_flag()));
    let bin = wrapped(&rustc, &optimised("mavtables", "bin"));
    assert!(
        bin.contains(&"metadata=mavtables-bin".to_string()),
        "{bin:?}"
    );
    assert_eq!(bin.last(), Some(&profile_flag()));
}

#[test]
fn other_crates_and_debug_builds_are_passed_through_unchanged() {
    let rustc = fake_rustc("unchanged", profile_llvm());
    let dependency = optimised("mio", "lib");
    assert_eq!(wrapped(&rustc, &dependency), dependency);
    let debug = [
        "--crate-name",
        "mavtables",
        "--crate-type",
        "lib",
        "-C",
        "metadata=0123456789abcdef",
    ];
    assert_eq!(wrapped(&rustc, &debug), debug);
}

#[test]
fn instrumented_builds_and_older_llvm_get_no_profile() {
    let rustc = fake_rustc("instrumented", profile_llvm());
    let mut generate = optimised("mavtables", "lib");
    generate.push("-Cprofile-generate=/tmp/counts");
    let got = wrapped(&rustc, &generate);
    // The names the counts are recorded under are those of the optimised build.
    assert!(
        got.contains(&"metadata=mavtables-lib".to_string()),
        "{got:?}"
    );
    assert!(
        !got.iter().any(|a| a.starts_with("-Cprofile-use")),
        "{got:?}"
    );
    let mut fuzzing = optimised("mavtables", "lib");
    fuzzing.extend(["-Cpasses=sancov-module", "-Zsanitizer=address"]);
    assert!(
        !wrapped(&rustc, &fuzzing)
            .iter()
            .any(|a| a.starts_with("-Cprofile-use"))
    );
    let old = fake_rustc("old-llvm", profile_llvm() - 1);
    let got = wrapped(&old, &optimised("mavtables", "lib"));
    assert!(
        !got.iter().any(|a| a.starts_with("-Cprofile-use")),
        "{got:?}"
    );
}
