//! The server side of the shared secret ([`strider_proto::secret`]): an interceptor that
//! refuses calls without it and lifts a connection's deadline once it has shown it.

use strider_proto::secret::Secret;
use tonic::{Request, Status};

/// A tonic interceptor that refuses calls without `secret`.
pub fn interceptor(secret: &Secret) -> impl Fn(Request<()>) -> Result<Request<()>, Status> + Clone {
    let secret = secret.clone();
    move |req: Request<()>| {
        match req.metadata().get("authorization") {
        Some(v) if secret.matches(v.as_bytes()) => {
            // The connection has shown the secret: its deadline no longer applies.
            if let Some(c) = req.extensions().get::<super::incoming::ConnectionInfo>() {
                c.mark_authenticated();
            }
            Ok(req)
        }
        Some(_) => Err(Status::unauthenticated(
            "wrong secret: a worker's --token-file (or STRIDER_SECRET) must hold the secret the coordinator's --token-file holds",
        )),
        None => Err(Status::unauthenticated(
            "missing secret: a worker takes it from --token-file FILE (the coordinator's secret) or STRIDER_SECRET; other clients send metadata `authorization: Bearer <secret>`",
        )),
    }
    }
}
