use super::*;
use glam::DQuat;
use proptest::prelude::*;

const ID_ROT: &str =
    "[1.000000 0.000000 0.000000 0.000000 1.000000 0.000000 0.000000 0.000000 1.000000]";

fn cfg() -> DtrackConfig {
    DtrackConfig::default()
}

fn parse(s: &str) -> Result<DtrackFrame, DtrackError> {
    parse_datagram(s.as_bytes(), &cfg())
}

fn flystick_line(q: &str, pos: &str, rot: &str, tail: &str) -> String {
    format!("6df2 1 1 [0 {q} 6 2][{pos}]{rot}{tail}")
}

#[test]
fn full_frame_with_every_record() {
    let text = format!(
        "fr 21753\nts 39596.024831\n6dcal 2\n6d 1 [0 1.000][326.848 -187.216 109.921]{ID_ROT}\n{}\n",
        flystick_line("1.000", "100.0 1500.0 1000.0", ID_ROT, "[5 0.5 -0.25]")
    );
    let f = parse(&text).unwrap();
    assert_eq!(f.frame_counter, Some(21753));
    assert_eq!(f.timestamp, Some(Timestamp::SinceMidnight(39596.024831)));
    assert_eq!(f.calibrated_bodies, Some(2));
    assert_eq!(f.bodies.len(), 1);
    let p = f.bodies[0].pose.unwrap();
    // mm → m.
    assert!((p.position - DVec3::new(0.326848, -0.187216, 0.109921)).length() < 1e-12);
    let s = &f.flysticks[0];
    assert_eq!((s.button_count, s.buttons), (6, 5));
    assert_eq!(s.axes, vec![0.5, -0.25]);
    assert!((s.pose.unwrap().position - DVec3::new(0.1, 1.5, 1.0)).length() < 1e-12);
}

#[test]
fn rotation_matrix_is_read_column_by_column() {
    // 90° about +Z: the first column is the image of x, i.e. (0, 1, 0).
    let rot = "[0 1 0 -1 0 0 0 0 1]";
    let f = parse(&format!("6d 1 [0 1.0][0 0 0]{rot}")).unwrap();
    let q = f.bodies[0].pose.unwrap().orientation;
    assert!((q * DVec3::X - DVec3::Y).length() < 1e-12);
    assert!((q * DVec3::Y + DVec3::X).length() < 1e-12);
}

#[test]
fn line_endings_lf_crlf_and_cr_parse_alike() {
    let lf = format!("fr 1\n6d 1 [3 1.0][1 2 3]{ID_ROT}\n");
    let crlf = lf.replace('\n', "\r\n");
    let cr = lf.replace('\n', "\r");
    let a = parse(&lf).unwrap();
    assert_eq!(parse(&crlf).unwrap(), a);
    assert_eq!(parse(&cr).unwrap(), a);
}

#[test]
fn trailing_nul_bytes_are_ignored() {
    let mut bytes = b"fr 7\n".to_vec();
    bytes.extend_from_slice(&[0, 0, 0]);
    let f = parse_datagram(&bytes, &cfg()).unwrap();
    assert_eq!(f.frame_counter, Some(7));
}

#[test]
fn nul_byte_inside_the_text_fails_the_frame() {
    let e = parse_datagram(b"fr 7\0\nts 1.0", &cfg()).unwrap_err();
    assert_eq!(e.kind.name(), "dtrack_not_text");
}

#[test]
fn six_value_position_block_drops_euler_angles() {
    let f = parse(&format!(
        "6d 1 [0 1.0][10 20 30 -160.86 -38.04 -118.44]{ID_ROT}"
    ))
    .unwrap();
    assert!((f.bodies[0].pose.unwrap().position - DVec3::new(0.01, 0.02, 0.03)).length() < 1e-15);
}

#[test]
fn four_value_position_block_is_an_error_naming_the_field() {
    let e = parse(&format!("fr 1\n6d 1 [0 1.0][10 20 30 40]{ID_ROT}")).unwrap_err();
    assert_eq!(e.line, 2);
    assert!(matches!(
        e.kind,
        DtrackErrorKind::BlockLength {
            field: "[position]",
            found: 4,
            ..
        }
    ));
    assert!(e.to_string().contains("line 2"));
}

#[test]
fn body_id_is_taken_from_the_block_not_the_index() {
    let f = parse(&format!(
        "6d 2 [4 1.0][0 0 0]{ID_ROT} [9 0.5][1 1 1]{ID_ROT}"
    ))
    .unwrap();
    let ids: Vec<u32> = f.bodies.iter().map(|b| b.id).collect();
    assert_eq!(ids, vec![4, 9]);
}

#[test]
fn duplicate_ids_fail_the_frame() {
    let e = parse(&format!(
        "6d 2 [4 1.0][0 0 0]{ID_ROT} [4 0.5][1 1 1]{ID_ROT}"
    ))
    .unwrap_err();
    assert!(matches!(e.kind, DtrackErrorKind::DuplicateId { id: 4, .. }));
}

#[test]
fn untracked_flystick_keeps_buttons_but_has_no_pose() {
    let zero = "[0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000]";
    let f = parse(&flystick_line("-1.000", "0 0 0", zero, "[1 0.0 0.8]")).unwrap();
    let s = &f.flysticks[0];
    assert_eq!(s.pose, None);
    assert_eq!(s.buttons, 1);
    assert_eq!(s.axes, vec![0.0, 0.8]);
    let mut out = Vec::new();
    let mut d = DtrackDecoder::new(cfg(), TimeSource::Receive);
    d.decode_into(
        flystick_line("-1.000", "0 0 0", zero, "[1 0.0 0.8]").as_bytes(),
        3.0,
        &mut out,
    )
    .unwrap();
    assert_eq!(out[0].pose, Some(Tracking::Lost));
    assert_eq!(out[0].buttons, Some(1));
}

#[test]
fn zero_rotation_with_positive_quality_is_still_untracked() {
    let zero = "[0 0 0 0 0 0 0 0 0]";
    let f = parse(&format!("6d 1 [0 1.0][1 2 3]{zero}")).unwrap();
    assert_eq!(f.bodies[0].pose, None);
}

#[test]
fn flystick2_plus_has_eight_buttons_and_three_axes() {
    let f = parse(&format!(
        "6df2 1 1 [0 1.0 8 3][0 0 0]{ID_ROT}[255 0.1 0.2 -0.3]"
    ))
    .unwrap();
    let s = &f.flysticks[0];
    assert_eq!((s.button_count, s.buttons), (8, 255));
    assert_eq!(s.axes, vec![0.1, 0.2, -0.3]);
}

#[test]
fn button_bits_beyond_the_count_are_masked() {
    let f = parse(&format!("6df2 1 1 [0 1.0 6 2][0 0 0]{ID_ROT}[255 0 0]")).unwrap();
    assert_eq!(f.flysticks[0].buttons, 0b11_1111);
}

#[test]
fn joystick_signs_apply_per_axis() {
    let config = DtrackConfig {
        joystick_signs: [-1.0, 1.0, -1.0],
        ..cfg()
    };
    let f = parse_datagram(
        format!("6df2 1 1 [0 1.0 8 3][0 0 0]{ID_ROT}[0 0.5 0.5 0.5]").as_bytes(),
        &config,
    )
    .unwrap();
    assert_eq!(f.flysticks[0].axes, vec![-0.5, 0.5, -0.5]);
}

#[test]
fn tracker_to_room_transform_applies_rotation_translation_and_units() {
    let config = DtrackConfig {
        tracker_to_room: TrackerToRoom {
            translation_m: [1.0, 0.0, 0.0],
            ..TrackerToRoom::z_up()
        },
        ..cfg()
    };
    config.tracker_to_room.validate().unwrap();
    // Tracker Z up: the point 1 m above the tracker origin is room (0, 1, 0) + offset.
    let f = parse_datagram(
        format!("6d 1 [0 1.0][0 0 1000]{ID_ROT}").as_bytes(),
        &config,
    )
    .unwrap();
    let p = f.bodies[0].pose.unwrap();
    assert!((p.position - DVec3::new(1.0, 1.0, 0.0)).length() < 1e-12);
    // A body aligned with the tracker frame points (−Z) at tracker −Z = room −Y.
    assert!((p.orientation * DVec3::NEG_Z - DVec3::NEG_Y).length() < 1e-12);
}

#[test]
fn mirror_transform_is_rejected() {
    let t = TrackerToRoom {
        rotation_rows: [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        ..TrackerToRoom::default()
    };
    assert!(matches!(
        t.validate(),
        Err(TransformError::NotRotation { .. })
    ));
}

#[test]
fn non_rotation_matrix_fails_the_frame() {
    let e = parse("fr 1\n6d 1 [0 1.0][0 0 0][2 0 0 0 1 0 0 0 1]").unwrap_err();
    assert!(matches!(e.kind, DtrackErrorKind::NotRotation { id: 0, .. }));
}

#[test]
fn unknown_lines_are_ignored() {
    let f = parse("fr 3\n3d 2 [1 1.0][1 2 3] [2 1.0][4 5 6]\n6dmt2 whatever\nfr2 9").unwrap();
    assert_eq!(f.frame_counter, Some(3));
}

#[test]
fn nan_and_infinity_are_rejected() {
    for bad in ["nan", "inf", "-inf", "infinity", "NaN"] {
        let e = parse(&format!("6d 1 [0 1.0][{bad} 0 0]{ID_ROT}")).unwrap_err();
        assert_eq!(e.kind.name(), "dtrack_non_finite", "{bad}");
    }
}

#[test]
fn huge_counts_are_rejected_before_any_allocation() {
    let e = parse("6d 4000000000 [0 1.0]").unwrap_err();
    assert_eq!(e.kind.name(), "dtrack_out_of_range");
    let e = parse("6d 99999999999999999999999").unwrap_err();
    assert_eq!(e.kind.name(), "dtrack_bad_token");
    let e = parse(&format!("6df2 1 1 [0 1.0 33 2][0 0 0]{ID_ROT}[0 0 0]")).unwrap_err();
    assert!(matches!(
        e.kind,
        DtrackErrorKind::OutOfRange {
            field: "button count",
            ..
        }
    ));
}

#[test]
fn count_larger_than_the_blocks_present_fails() {
    let e = parse(&format!("6d 2 [0 1.0][0 0 0]{ID_ROT}")).unwrap_err();
    assert!(matches!(e.kind, DtrackErrorKind::Missing { .. }));
}

#[test]
fn trailing_text_on_a_known_record_fails() {
    let e = parse("fr 1 2").unwrap_err();
    assert_eq!(e.kind.name(), "dtrack_trailing_text");
}

#[test]
fn stick_deflection_outside_unit_range_fails() {
    let e = parse(&format!("6df2 1 1 [0 1.0 6 2][0 0 0]{ID_ROT}[0 1.5 0]")).unwrap_err();
    assert!(matches!(
        e.kind,
        DtrackErrorKind::OutOfRange {
            field: "controller",
            ..
        }
    ));
}

#[test]
fn oversized_datagram_is_rejected() {
    let big = vec![b' '; MAX_DATAGRAM + 1];
    let e = parse_datagram(&big, &cfg()).unwrap_err();
    assert_eq!((e.line, e.kind.name()), (0, "dtrack_oversized"));
}

#[test]
fn ts2_gives_unix_seconds_and_microseconds_and_tolerates_extensions() {
    let f = parse("ts2 1700000000 250000").unwrap();
    assert_eq!(
        f.timestamp,
        Some(Timestamp::Unix {
            sec: 1_700_000_000,
            usec: 250_000
        })
    );
    let f = parse("ts2 1700000000 250000 1200").unwrap();
    assert!(f.timestamp.is_some());
    assert!(parse("ts2 1700000000 1000000").is_err());
    let mut d = DtrackDecoder::new(cfg(), TimeSource::Tracker);
    let mut out = Vec::new();
    d.decode_into(
        format!("ts2 1700000000 250000\n6d 1 [0 1.0][0 0 0]{ID_ROT}").as_bytes(),
        0.0,
        &mut out,
    )
    .unwrap();
    assert!((out[0].t - 1_700_000_000.25).abs() < 1e-6);
}

#[test]
fn ts_midnight_wrap_keeps_time_increasing() {
    let mut d = DtrackDecoder::new(cfg(), TimeSource::Tracker);
    let mut times = Vec::new();
    for ts in [86399.98, 86399.99, 0.0, 0.01, 0.02] {
        let mut out = Vec::new();
        d.decode_into(
            format!("ts {ts}\n6d 1 [0 1.0][0 0 0]{ID_ROT}").as_bytes(),
            0.0,
            &mut out,
        )
        .unwrap();
        times.push(out[0].t);
    }
    for w in times.windows(2) {
        assert!(w[1] > w[0] && w[1] - w[0] < 0.011, "{times:?}");
    }
    assert!((times[4] - (SECONDS_PER_DAY + 0.02)).abs() < 1e-9);
}

#[test]
fn ts_out_of_day_range_fails() {
    assert!(parse("ts 90000.0").is_err());
    assert!(parse("ts -1.0").is_err());
}

#[test]
fn receive_time_is_used_without_timestamp_or_when_configured() {
    let text = format!("ts 100.0\n6d 1 [0 1.0][0 0 0]{ID_ROT}");
    let mut out = Vec::new();
    DtrackDecoder::new(cfg(), TimeSource::Receive)
        .decode_into(text.as_bytes(), 7.5, &mut out)
        .unwrap();
    assert_eq!(out[0].t, 7.5);
}

#[test]
fn formatted_flystick_parses_back() {
    let r = DMat3::from_quat(DQuat::from_euler(glam::EulerRot::YXZ, 0.3, -0.2, 0.1));
    let line = format!(
        "6df2 1 1 {}",
        format_flystick_block(
            0,
            Some((DVec3::new(10.0, 1500.0, 900.0), r)),
            6,
            3,
            &[0.25, -1.0]
        )
    );
    let f = parse(&line).unwrap();
    let s = &f.flysticks[0];
    let q = s.pose.unwrap().orientation;
    assert!(q.angle_between(DQuat::from_mat3(&r)) < 1e-5);
    assert_eq!(s.axes, vec![0.25, -1.0]);
    let lost = format!(
        "6df2 1 1 {}",
        format_flystick_block(0, None, 8, 1, &[0.0, 0.0, 0.0])
    );
    assert_eq!(parse(&lost).unwrap().flysticks[0].pose, None);
}

proptest! {
    #[test]
    fn arbitrary_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = parse_datagram(&data, &cfg());
    }

    #[test]
    fn mutated_valid_frames_never_panic_and_poses_stay_valid(
        cut in 0usize..400, byte in any::<u8>(), at in 0usize..400,
    ) {
        let mut text = format!("fr 1\nts 5.0\n{}", flystick_line("1.0", "1 2 3", ID_ROT, "[3 0.5 0.5]")).into_bytes();
        if at < text.len() { text[at] = byte; }
        text.truncate(cut.min(text.len()));
        if let Ok(f) = parse_datagram(&text, &cfg()) {
            for s in &f.flysticks {
                prop_assert!(s.pose.is_none_or(|p| p.is_valid()));
                prop_assert!(s.axes.iter().all(|a| a.is_finite()));
            }
        }
    }
}
