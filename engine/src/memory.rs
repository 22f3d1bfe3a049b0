//! What a session's state holds in memory: the bytes of the buffers it owns, by capacity
//! (what the allocator gave, not what is in use). Data shared between sessions — a loaded
//! bundle, a tearing vademecum — belongs to the bundle and is not counted here.

/// Bytes of the buffer of `v` (its capacity; the elements' own heap is the caller's to add).
pub fn vec_bytes<T>(v: &Vec<T>) -> usize {
    v.capacity() * std::mem::size_of::<T>()
}

/// Bytes of a slice behind a box or a shared pointer.
pub fn slice_bytes<T>(v: &[T]) -> usize {
    std::mem::size_of_val(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_count_their_capacity() {
        let mut v: Vec<f64> = Vec::with_capacity(10);
        v.push(1.0);
        assert_eq!(vec_bytes(&v), 80);
        let s: std::sync::Arc<[u32]> = vec![1u32; 7].into();
        assert_eq!(slice_bytes(&s), 28);
    }
}
