//! Tests of the readers' packets (exact bytes at the documented C offsets, corrupt packets
//! refused without panicking) and of the client's server check against a socket of this test.

use std::io::Write;

use super::*;

/// A patterned record body: byte i is `i * 7 + 3`, padding zeroed where `padding` says.
fn patterned(size: usize, padding: std::ops::Range<usize>) -> Vec<u8> {
    (0..size)
        .map(|i| {
            if padding.contains(&i) {
                0
            } else {
                (i * 7 + 3) as u8
            }
        })
        .collect()
}

fn round_trips<T: WireRecord>(padding: std::ops::Range<usize>) {
    assert_eq!(T::SIZE, std::mem::size_of::<T>(), "{}", T::TYPE_NAME);
    let body = patterned(T::SIZE, padding);
    let record = T::decode(&body);
    let mut packet = Vec::new();
    encode_packet(&record, &mut packet);
    assert_eq!(&packet[HEADER_LEN..], &body[..], "{}", T::TYPE_NAME);
    assert_eq!(&packet[..4], b"IMRD");
    assert_eq!(packet[6], T::CODE);
    set_dropped(&mut packet, 0x0102_0304_0506_0708);
    let (dropped, received) = decode_packet(&packet).unwrap();
    assert_eq!(dropped, 0x0102_0304_0506_0708);
    let back = T::take(received).expect("same stream");
    let mut again = Vec::new();
    encode_packet(&back, &mut again);
    assert_eq!(&again[HEADER_LEN..], &body[..], "{}", T::TYPE_NAME);
}

#[test]
fn every_record_round_trips_byte_for_byte() {
    round_trips::<RawSample>(84..88);
    round_trips::<CorrectedSample>(0..0);
    round_trips::<DaemonStatus>(0..0);
    round_trips::<CalibrationHealth>(0..0);
}

fn body<T: WireRecord>(record: &T) -> Vec<u8> {
    let mut packet = Vec::new();
    encode_packet(record, &mut packet);
    packet.split_off(HEADER_LEN)
}

fn at<const N: usize>(bytes: &[u8], offset: usize) -> [u8; N] {
    bytes[offset..offset + N].try_into().unwrap()
}

#[test]
fn fields_sit_at_the_documented_c_offsets() {
    let raw = body(&RawSample {
        seq: 11,
        mag_counts: [0, 0, -5],
        temp_c: 21.5,
        ticks: 0xBEEF,
        command: 0x0C,
        flags: 0x8000_0001,
        mag_device_gauss: [0.0, 0.0, 0.25],
        ..RawSample::default()
    });
    assert_eq!(at::<8>(&raw, 0), 11u64.to_le_bytes());
    assert_eq!(at::<4>(&raw, 80), (-5i32).to_le_bytes());
    assert_eq!(at::<8>(&raw, 88), 21.5f64.to_le_bytes());
    assert_eq!(at::<2>(&raw, 96), 0xBEEFu16.to_le_bytes());
    assert_eq!(raw[98], 0x0C);
    assert_eq!(at::<4>(&raw, 100), 0x8000_0001u32.to_le_bytes());
    assert_eq!(at::<8>(&raw, 168), 0.25f64.to_le_bytes());

    let corrected = body(&CorrectedSample {
        gyro_rad_s: [0.0, 0.5, 0.0],
        calibration_id: 0xABCD,
        reserved: 7,
        ..CorrectedSample::default()
    });
    assert_eq!(at::<8>(&corrected, 64), 0.5f64.to_le_bytes());
    assert_eq!(at::<8>(&corrected, 112), 0xABCDu64.to_le_bytes());
    assert_eq!(at::<4>(&corrected, 124), 7u32.to_le_bytes());

    let status = body(&DaemonStatus {
        calibration_id: 9,
        protocol: 1,
        clock_offset_s: -1.5,
        gain_scale_mag: 0x1234,
        fields_skipped: 77,
        time_sync: 3,
        gnss_drift_ppm: 150.0,
        gnss_lost_transitions: 5,
        ..DaemonStatus::default()
    });
    assert_eq!(at::<8>(&status, 88), 9u64.to_le_bytes());
    assert_eq!(status[125], 1);
    assert_eq!(at::<8>(&status, 128), (-1.5f64).to_le_bytes());
    assert_eq!(at::<2>(&status, 148), 0x1234u16.to_le_bytes());
    assert_eq!(at::<8>(&status, 160), 77u64.to_le_bytes());
    assert_eq!(status[169], 3);
    // An older imud's status (v3, before the time sync) reads with the time sync unknown.
    let mut packet = Vec::new();
    encode_packet(
        &DaemonStatus {
            fields_skipped: 77,
            time_sync: 3,
            ..DaemonStatus::default()
        },
        &mut packet,
    );
    let Ok((_, Received::Status(v3))) = decode_packet(&packet[..HEADER_LEN + 168]) else {
        panic!("a v3 status is refused");
    };
    assert_eq!((v3.fields_skipped, v3.time_sync), (77, 0));
    assert!(v3.gnss_minus_wall_s.is_nan() && v3.gnss_drift_ppm.is_nan());
    assert_eq!(at::<8>(&status, 184), 150f64.to_le_bytes());
    assert_eq!(at::<8>(&status, 200), 5u64.to_le_bytes());

    let health = body(&CalibrationHealth {
        gravity_m_s2: 9.81,
        gyro_offset_rad_s: [0.0, 0.0, 1e-3],
        bias_tracking: 1,
        ..CalibrationHealth::default()
    });
    assert_eq!(at::<8>(&health, 144), 1e-3f64.to_le_bytes());
    assert_eq!(at::<8>(&health, 152), 9.81f64.to_le_bytes());
    assert_eq!(health[172], 1);
}

#[test]
fn corrupt_packets_are_refused_with_the_reason() {
    let mut good = Vec::new();
    encode_packet(&CorrectedSample::default(), &mut good);
    // Every truncation is an error, never a panic.
    for len in 0..good.len() {
        assert!(decode_packet(&good[..len]).is_err(), "{len}");
    }
    assert_eq!(
        decode_packet(&good[..3]),
        Err(PacketError::Short { len: 3 })
    );
    let mut bad = good.clone();
    bad[0] = b'X';
    assert!(matches!(
        decode_packet(&bad),
        Err(PacketError::Magic { .. })
    ));
    let mut bad = good.clone();
    bad[4] = 2;
    assert_eq!(decode_packet(&bad), Err(PacketError::Version { found: 2 }));
    let mut bad = good.clone();
    bad[6] = 9;
    assert_eq!(decode_packet(&bad), Err(PacketError::Stream { code: 9 }));
    let mut bad = good.clone();
    bad[6] = RawSample::CODE;
    assert_eq!(
        decode_packet(&bad),
        Err(PacketError::Length {
            code: 1,
            expected: 176,
            found: 128
        })
    );
    let mut long = good.clone();
    long.push(0);
    assert!(matches!(
        decode_packet(&long),
        Err(PacketError::Length { found: 129, .. })
    ));
}

/// A listening SOCK_SEQPACKET socket of this process at `path`.
fn listen(path: &Path) -> Socket {
    let s = Socket::new(Domain::UNIX, Type::SEQPACKET, None).unwrap();
    s.bind(&SockAddr::unix(path).unwrap()).unwrap();
    s.listen(4).unwrap();
    s
}

#[test]
fn the_client_trusts_only_the_users_it_was_given_and_counts_gaps() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("readers.sock");
    let listener = listen(&path);
    let me = UserId::current();

    // A server of another user than the trusted ones is refused, naming who serves.
    let other = TrustedPublishers::users(vec![UserId(me.0.wrapping_add(1))]);
    let err = ReadersClient::connect(&path, &other, Duration::ZERO).unwrap_err();
    assert!(
        matches!(err, ReadersError::UntrustedServer { server, .. }
            if server.user == Some(me) && server.pid == std::process::id() as i32),
        "{err}"
    );
    assert!(
        err.to_string().contains("not a trusted imud publisher"),
        "{err}"
    );
    drop(listener.accept().unwrap());

    let mine = TrustedPublishers::users(vec![me]);
    let mut client = ReadersClient::connect(&path, &mine, Duration::ZERO).unwrap();
    let (mut conn, _) = listener.accept().unwrap();
    let mut packet = Vec::new();
    for seq in [5u64, 6, 9] {
        encode_packet(
            &CorrectedSample {
                seq,
                ..CorrectedSample::default()
            },
            &mut packet,
        );
        set_dropped(&mut packet, seq / 9 * 2);
        conn.write_all(&packet).unwrap();
    }
    let mut seqs = Vec::new();
    while let Some(r) = client.recv(Duration::from_secs(5)).unwrap() {
        seqs.push(r.seq().unwrap());
        if seqs.len() == 3 {
            break;
        }
    }
    assert_eq!(seqs, [5, 6, 9]);
    assert_eq!(client.missed(), 2);
    assert_eq!(client.server_dropped(), 2);
    // Nothing more within the timeout; then the server goes away.
    assert!(client.recv(Duration::from_millis(1)).unwrap().is_none());
    conn.write_all(b"junk").unwrap();
    assert!(matches!(
        client.recv(Duration::from_secs(5)),
        Err(ReadersError::Packet {
            source: PacketError::Short { len: 4 },
            ..
        })
    ));
    drop(conn);
    assert!(matches!(
        client.recv(Duration::from_secs(5)),
        Err(ReadersError::Closed { .. })
    ));
}

#[test]
fn a_missing_socket_is_reported_as_no_imud_running() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("none.sock");
    let trusted = TrustedPublishers::default_for_this_process();
    let err = ReadersClient::connect(&path, &trusted, Duration::ZERO).unwrap_err();
    assert!(matches!(err, ReadersError::NotRunning { .. }), "{err}");
    assert!(err.to_string().contains("none.sock"), "{err}");
}
