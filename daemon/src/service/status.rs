//! The one place internal errors become gRPC statuses. Clients see the
//! error's message, never Debug output.

use tonic::Status;

use crate::tiles::TileError;

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
