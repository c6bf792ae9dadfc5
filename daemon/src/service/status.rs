//! The one place internal errors become gRPC statuses, and statuses HTTP
//! answers. Clients see the error's message, never Debug output.

use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use tonic::{Code, Status};

use crate::tiles::TileError;
use crate::view::ViewError;

pub fn from_tile_error(e: &TileError) -> Status {
    let message = e.to_string();
    match e {
        TileError::UnknownSource(_) => Status::not_found(message),
        TileError::OutsideGrid { .. } => Status::invalid_argument(message),
        TileError::Unavailable { .. } => Status::failed_precondition(message),
        TileError::Generate { .. } => Status::internal(message),
        TileError::Cancelled => Status::unavailable(message),
    }
}

/// A request field that does not hold a usable value.
pub fn invalid_field(field: &str, message: impl std::fmt::Display) -> Status {
    Status::invalid_argument(format!("invalid field '{field}': {message}"))
}

pub fn from_view_error(e: &ViewError) -> Status {
    let message = e.to_string();
    match e {
        ViewError::Invalid(_) => Status::invalid_argument(message),
        ViewError::Busy | ViewError::TooManyViews(_) => Status::resource_exhausted(message),
        ViewError::NoDevice(_) => Status::unavailable(message),
        ViewError::UnknownView(_) | ViewError::UnknownSource(_) => Status::not_found(message),
        ViewError::NoFrame(_) => Status::failed_precondition(message),
    }
}

/// A call's failure as HTTP: the status that matches its gRPC code, and
/// `{"code": "INVALID_ARGUMENT", "message": "..."}`.
pub struct HttpError(pub(super) Status);

impl From<Status> for HttpError {
    fn from(s: Status) -> Self {
        Self(s)
    }
}

fn http_status(code: Code) -> StatusCode {
    match code {
        Code::Ok => StatusCode::OK,
        Code::InvalidArgument | Code::FailedPrecondition | Code::OutOfRange => StatusCode::BAD_REQUEST,
        Code::NotFound => StatusCode::NOT_FOUND,
        Code::AlreadyExists | Code::Aborted => StatusCode::CONFLICT,
        Code::PermissionDenied => StatusCode::FORBIDDEN,
        Code::Unauthenticated => StatusCode::UNAUTHORIZED,
        Code::ResourceExhausted => StatusCode::TOO_MANY_REQUESTS,
        Code::Unimplemented => StatusCode::NOT_IMPLEMENTED,
        Code::Unavailable => StatusCode::SERVICE_UNAVAILABLE,
        Code::DeadlineExceeded => StatusCode::GATEWAY_TIMEOUT,
        Code::Cancelled => StatusCode::from_u16(499).unwrap_or(StatusCode::BAD_REQUEST),
        Code::Unknown | Code::Internal | Code::DataLoss => StatusCode::INTERNAL_SERVER_ERROR,
    }
}

pub fn error_body(s: &Status) -> serde_json::Value {
    let code = format!("{:?}", s.code());
    // "InvalidArgument" -> "INVALID_ARGUMENT", as gRPC names its codes.
    let mut name = String::new();
    for (i, c) in code.chars().enumerate() {
        if c.is_uppercase() && i > 0 {
            name.push('_');
        }
        name.push(c.to_ascii_uppercase());
    }
    serde_json::json!({ "code": name, "message": s.message() })
}

impl IntoResponse for HttpError {
    fn into_response(self) -> Response {
        (http_status(self.0.code()), axum::Json(error_body(&self.0))).into_response()
    }
}
