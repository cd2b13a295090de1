/// The commit a checkout at `dir` is at, with `-dirty` when its tree differs from it (a file
/// changed, staged or not, or one git does not ignore added): a run made by a build of a
/// modified tree must not claim the clean commit's name. None without git or a checkout.
pub fn commit_of(dir: &std::path::Path) -> Option<String> {
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .current_dir(dir)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let commit = git(&["rev-parse", "HEAD"]).filter(|c| !c.is_empty())?;
    let changed = git(&["status", "--porcelain"]).is_none_or(|s| !s.is_empty());
    Some(if changed { format!("{commit}-dirty") } else { commit })
}
