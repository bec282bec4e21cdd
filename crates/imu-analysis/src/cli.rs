//! What the command-line clients share beyond the analyses: telling a closed output pipe
//! (`imu-noise rec.mcap --json | head`) from a real failure.

/// True if any error in `chain` (an error and its sources) is an I/O error of kind
/// `BrokenPipe`, directly or inside a JSON writer's error: the reader went away, which is not
/// the tool's failure.
pub fn is_broken_pipe<'a>(
    mut chain: impl Iterator<Item = &'a (dyn std::error::Error + 'static)>,
) -> bool {
    chain.any(|c| {
        c.downcast_ref::<std::io::Error>()
            .map(std::io::Error::kind)
            .or_else(|| {
                c.downcast_ref::<serde_json::Error>()
                    .and_then(serde_json::Error::io_error_kind)
            })
            == Some(std::io::ErrorKind::BrokenPipe)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("writing the table")]
    struct Wrapper(#[source] std::io::Error);

    #[test]
    fn broken_pipes_are_found_through_sources_and_json() {
        let io = || std::io::Error::from(std::io::ErrorKind::BrokenPipe);
        let w = Wrapper(io());
        let chain = || {
            std::iter::successors(Some(&w as &(dyn std::error::Error + 'static)), |e| {
                e.source()
            })
        };
        assert!(is_broken_pipe(chain()));
        let j = serde_json::Error::io(io());
        assert!(is_broken_pipe(std::iter::once(
            &j as &(dyn std::error::Error + 'static)
        )));
        let other = Wrapper(std::io::Error::from(std::io::ErrorKind::NotFound));
        assert!(!is_broken_pipe(std::iter::once(
            &other as &(dyn std::error::Error + 'static)
        )));
    }
}
