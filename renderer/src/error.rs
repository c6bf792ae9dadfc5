use thiserror::Error;

#[derive(Debug, Error)]
pub enum RenderError {
    #[error("invalid camera: field '{field}': {message}")]
    Camera { field: &'static str, message: String },
    #[error("invalid render request: field '{field}': {message}")]
    Request { field: &'static str, message: String },
    #[error("no GPU adapter (not even Mesa's lavapipe): {0}")]
    NoAdapter(String),
    #[error("the GPU device failed: {0}")]
    Device(String),
}
