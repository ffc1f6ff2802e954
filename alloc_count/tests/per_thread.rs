//! The count is per thread: another thread allocating while this one counts changes nothing.

#[global_allocator]
static ALLOC: alloc_count::Counting = alloc_count::Counting;

#[test]
fn other_threads_do_not_count() {
    let (v, n) = alloc_count::count(|| vec![1u8; 64]);
    assert_eq!(n, 1);
    let (sum, n) = alloc_count::count(|| {
        // Another thread allocates thousands of times while this one counts.
        std::thread::scope(|s| {
            s.spawn(|| (0..10_000).map(|i| vec![i as u8; 16].len()).sum::<usize>())
                .join()
                .unwrap()
        })
    });
    assert_eq!(sum, 160_000);
    // Spawning a thread allocates on this thread (its name, its handle), but a bounded
    // number of times: not ten thousand.
    assert!(n < 100, "{n}");
    let (_, n) = alloc_count::count(|| v.iter().map(|&b| u32::from(b)).sum::<u32>());
    assert_eq!(n, 0);
}
