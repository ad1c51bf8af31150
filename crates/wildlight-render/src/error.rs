//! Errors of the renderer's settings.

/// An invalid renderer setting.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RenderError {
    /// A setting is out of its valid range.
    #[error("invalid render setting `{name}` = {value}: {reason}")]
    InvalidSetting {
        /// The setting's name.
        name: &'static str,
        /// Its value, as text.
        value: String,
        /// What is wrong with it.
        reason: &'static str,
    },
}

/// Returns an [`RenderError::InvalidSetting`] unless `ok`.
pub(crate) fn check(
    ok: bool,
    name: &'static str,
    value: impl std::fmt::Display,
    reason: &'static str,
) -> Result<(), RenderError> {
    if ok {
        Ok(())
    } else {
        Err(RenderError::InvalidSetting {
            name,
            value: value.to_string(),
            reason,
        })
    }
}
