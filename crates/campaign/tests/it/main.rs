//! The sharding rules of `campaign`: the `K/N` parser, the dealing rule (every item in exactly one shard, by the
//! stated rule), shard files that return every f64 bit for bit, and a merge that restores the item order and
//! refuses incomplete or mixed sets of shards.

use campaign::{merge, read, read_header, write, Shard, ShardError, ShardFile, ShardSpecError};
use std::path::PathBuf;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("campaign_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn shard_specs_parse_and_bad_ones_say_why() {
    let s: Shard = "2/3".parse().expect("2/3");
    assert_eq!((s.index(), s.count(), s.to_string()), (2, 3, "2/3".to_string()));
    assert_eq!(" 1 / 1 ".parse::<Shard>(), Ok(Shard::WHOLE));
    assert_eq!("0/3".parse::<Shard>(), Err(ShardSpecError::Zero { index: 0, count: 3 }));
    assert_eq!("1/0".parse::<Shard>(), Err(ShardSpecError::Zero { index: 1, count: 0 }));
    assert_eq!("4/3".parse::<Shard>(), Err(ShardSpecError::OutOfRange { index: 4, count: 3 }));
    for bad in ["", "3", "1/3/4", "a/3", "-1/3", "1.5/3", "1/"] {
        assert_eq!(bad.parse::<Shard>(), Err(ShardSpecError::Syntax(bad.into())), "{bad:?}");
    }
}

#[test]
fn dealing_gives_every_item_to_exactly_one_shard_round_robin() {
    for n in 1..=5u32 {
        for total in 0..23usize {
            let mut owner = vec![0u32; total];
            for k in 1..=n {
                let s = Shard::new(k, n).expect("shard");
                let items: Vec<usize> = s.items(total).collect();
                assert!(items.windows(2).all(|w| w[0] < w[1]), "{s}: ascending");
                for i in items {
                    assert_eq!(owner[i], 0, "item {i} of {total} dealt twice");
                    assert!(s.owns(i));
                    owner[i] = k;
                }
            }
            // The documented rule, written out: item i belongs to shard i mod N + 1.
            let rule: Vec<u32> = (0..total).map(|i| (i % n as usize) as u32 + 1).collect();
            assert_eq!(owner, rule, "{total} items in {n} shards");
        }
    }
}

/// Values JSON would lose: NaN and infinities (written as null), and decimals whose shortest form serde_json's
/// default parser may read one unit in the last place off.
const AWKWARD: [f64; 9] =
    [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.0, 5e-324, 0.1 + 0.2, 130.65331632653061, f64::MAX, 1.0 / 3.0];

type File = ShardFile<String, (u64, Vec<f64>, Option<f64>)>;

fn shard_file(k: u32, n: u32, total: usize, config: &str) -> File {
    let shard = Shard::new(k, n).expect("shard");
    let items = shard.items(total).map(|i| (i, (i as u64, AWKWARD.to_vec(), Some(i as f64 / 7.0)))).collect();
    ShardFile {
        format: campaign::FORMAT_VERSION,
        kind: "test".into(),
        producer: "campaign tests".into(),
        shard,
        total,
        config: config.into(),
        items,
    }
}

#[test]
fn shard_files_keep_every_bit() {
    let dir = tmp("bits");
    let f = shard_file(2, 3, 8, "c");
    let path = write(&dir, &f).expect("write");
    assert_eq!(path.file_name().and_then(|n| n.to_str()), Some("shard-2-of-3.cbor"));
    let h = read_header(&path).expect("header");
    assert_eq!((h.kind.as_str(), h.shard, h.total), ("test", f.shard, 8));
    let back: File = read(&path, "test").expect("read");
    assert_eq!(back.items.len(), f.items.len());
    for ((i, (s, v, o)), (j, (t, w, p))) in f.items.iter().zip(&back.items) {
        assert_eq!((i, s), (j, t));
        assert!(w[0].is_nan());
        assert_eq!(
            v[1..].iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            w[1..].iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(o.map(f64::to_bits), p.map(f64::to_bits));
    }
    assert!(matches!(
        read::<String, (u64, Vec<f64>, Option<f64>)>(&path, "diff"),
        Err(ShardError::KindMismatch { .. })
    ));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn merge_restores_item_order_and_refuses_bad_sets() {
    let at = |k: u32| PathBuf::from(format!("s{k}"));
    let set = |n: u32, cfg: &dyn Fn(u32) -> &'static str| -> Vec<(PathBuf, File)> {
        (1..=n).rev().map(|k| (at(k), shard_file(k, n, 10, cfg(k)))).collect()
    };
    let (config, items) = merge(set(3, &|_| "c")).expect("merge");
    assert_eq!(config, "c");
    assert_eq!(items.iter().map(|x| x.0).collect::<Vec<_>>(), (0..10).collect::<Vec<u64>>());

    let mut missing = set(3, &|_| "c");
    missing.retain(|(p, _)| p != &at(2));
    assert!(matches!(merge(missing), Err(ShardError::MissingShards { missing, count: 3 }) if missing == [2]));

    let mut dup = set(3, &|_| "c");
    dup.push((PathBuf::from("again"), shard_file(1, 3, 10, "c")));
    assert!(matches!(merge(dup), Err(ShardError::DuplicateShard { .. })));

    assert!(matches!(merge(set(3, &|k| if k == 1 { "d" } else { "c" })), Err(ShardError::ConfigMismatch { .. })));

    let mut counts = set(3, &|_| "c");
    counts.push((PathBuf::from("other"), shard_file(1, 2, 10, "c")));
    assert!(matches!(merge(counts), Err(ShardError::CountMismatch { expected: 3, found: 2, .. })));

    let mut totals = set(2, &|_| "c");
    totals[0].1.total = 11;
    assert!(matches!(merge(totals), Err(ShardError::TotalMismatch { .. })));

    let mut wrong = set(3, &|_| "c");
    wrong[0].1.items.pop();
    assert!(matches!(merge(wrong), Err(ShardError::WrongItems { .. })));

    let mut kinds = set(3, &|_| "c");
    kinds[1].1.kind = "validate".into();
    assert!(matches!(merge(kinds), Err(ShardError::KindMismatch { .. })));

    assert!(matches!(merge(Vec::<(PathBuf, File)>::new()), Err(ShardError::Empty)));
}
