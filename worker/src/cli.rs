//! What the command lines share: telling a reader that closed the pipe from a real error.

/// Whether `e` comes from writing to a pipe whose reader has gone (`strider-coordinator
/// analyse | head`): the reader had enough, so the command ends quietly with success.
/// SIGPIPE is left ignored, as Rust sets it: the same binaries serve gRPC, where a peer
/// that goes away must not kill the process.
pub fn closed_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .map(|io| io.kind())
            .or_else(|| {
                cause
                    .downcast_ref::<serde_json::Error>()
                    .and_then(|j| j.io_error_kind())
            })
            == Some(std::io::ErrorKind::BrokenPipe)
    })
}
