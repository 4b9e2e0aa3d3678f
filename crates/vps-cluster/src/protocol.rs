//! The cluster's wire formats ([`vps_cluster_core::protocol`], re-exported here: datagrams and
//! join messages, strict decoding) and the join stream's framing on a QUIC reliable stream: each
//! message a `len: u64` and its body, the length checked against the caller's limit before
//! anything is allocated.

pub use vps_cluster_core::protocol::*;

use crate::ClusterError;

/// Writes one length-prefixed frame to a reliable stream.
pub async fn write_frame(send: &mut quinn::SendStream, body: &[u8]) -> Result<(), ClusterError> {
    send.write_all(&(body.len() as u64).to_le_bytes())
        .await
        .map_err(|e| ClusterError::Join(format!("write: {e}")))?;
    send.write_all(body)
        .await
        .map_err(|e| ClusterError::Join(format!("write: {e}")))
}

/// Reads one length-prefixed frame of at most `limit` bytes from a reliable stream (the length is
/// checked before anything is allocated).
pub async fn read_frame(recv: &mut quinn::RecvStream, limit: u64) -> Result<Vec<u8>, ClusterError> {
    let mut len = [0u8; 8];
    recv.read_exact(&mut len)
        .await
        .map_err(|e| ClusterError::Join(format!("read: {e}")))?;
    let len = u64::from_le_bytes(len);
    if len > limit {
        return Err(ClusterError::Join(format!(
            "message of {len} bytes exceeds the limit of {limit}"
        )));
    }
    let mut body = vec![0u8; len as usize];
    recv.read_exact(&mut body)
        .await
        .map_err(|e| ClusterError::Join(format!("read: {e}")))?;
    Ok(body)
}

/// Reads and decodes one join message.
pub async fn read_join(recv: &mut quinn::RecvStream) -> Result<JoinMessage, ClusterError> {
    let body = read_frame(recv, MAX_JOIN_MESSAGE).await?;
    JoinMessage::decode(&body).map_err(|e| ClusterError::Join(format!("join message: {e}")))
}

/// Encodes and writes one join message.
pub async fn write_join(
    send: &mut quinn::SendStream,
    message: &JoinMessage,
) -> Result<(), ClusterError> {
    write_frame(send, &message.encode()).await
}
