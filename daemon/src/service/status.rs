//! The one place internal errors become gRPC statuses. Clients see the
//! error's message, never Debug output.

use tonic::Status;

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
