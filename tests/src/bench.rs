//! What the bench binaries of every crate share: medians, CPU time,
//! settings from the environment, and a running reliefd's state.

pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// CPU seconds this process has used so far, every thread together (user
/// and system, from /proc/self/stat in Linux's 100 ticks a second): steadier
/// than wall time on a busy 2-core machine. NaN where it cannot be read.
pub fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else { return f64::NAN };
    // Fields after the command name, which is in parentheses: utime and stime are the 12th and 13th.
    let fields: Vec<&str> = stat.rsplit_once(')').map_or(Vec::new(), |(_, rest)| rest.split_whitespace().collect());
    let tick = |i: usize| fields.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(f64::NAN);
    (tick(11) + tick(12)) / 100.0
}

/// True when environment variable `var` (names separated by commas) is
/// unset or empty, or names `name`: which tables or datasets a bench runs.
pub fn wanted(var: &str, name: &str) -> bool {
    let only = std::env::var(var).unwrap_or_default();
    only.trim().is_empty() || only.split(',').any(|n| n.trim() == name)
}

/// The number in environment variable `name`, or `default`.
pub fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

/// The daemon's GetState answer.
pub async fn state(channel: &tonic::transport::Channel) -> anyhow::Result<relief_proto::v1::SceneState> {
    let mut client = relief_proto::v1::scene_service_client::SceneServiceClient::new(channel.clone());
    Ok(client.get_state(relief_proto::v1::GetStateRequest {}).await?.into_inner())
}
