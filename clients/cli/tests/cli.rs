//! The `relief` binary on its own: its commands, and a clear error when no
//! reliefd answers. (Against a running reliefd it is tested in `tests/`.)
//! Having a test here also makes `cargo test` build the binary, so one
//! build serves the bins, the tests and the benches.

use std::process::Command;

#[test]
fn help_lists_every_command() -> Result<(), Box<dyn std::error::Error>> {
    let out = Command::new(env!("CARGO_BIN_EXE_relief")).arg("--help").output()?;
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout)?;
    for command in ["state", "watch", "wait", "tile", "elevation", "reload", "render", "camera"] {
        assert!(text.contains(&format!("\n  {command} ")), "'{command}' missing from:\n{text}");
    }
    Ok(())
}

#[test]
fn an_unreachable_or_malformed_server_is_named_in_plain_words() -> Result<(), Box<dyn std::error::Error>> {
    for (server, words) in
        [("http://127.0.0.1:1", "Connection refused"), ("nonsense", "invalid URL, scheme is missing")]
    {
        let out = Command::new(env!("CARGO_BIN_EXE_relief")).args(["--server", server, "state"]).output()?;
        assert_eq!(out.status.code(), Some(1), "{server}");
        let text = String::from_utf8(out.stderr)?;
        assert!(text.starts_with(&format!("relief: cannot reach reliefd at {server}: ")), "{text}");
        assert!(text.contains(words) && !text.contains("{ ") && !text.contains("panicked"), "{text}");
    }
    Ok(())
}
