// `sqlx::migrate!` embeds coordinator/migrations at compile time; without this, adding a
// migration file does not rebuild the crate and an incremental build runs without it.
fn main() {
    println!("cargo:rerun-if-changed=migrations");
}
