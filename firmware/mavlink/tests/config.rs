//! The configuration's checks name the field and keep the value.

use wmr_mavlink::{ConfigKey, EndpointConfig, EndpointSpec};

#[test]
fn each_field_is_checked_by_name() {
    let ok = EndpointSpec::default();
    assert!(EndpointConfig::new(&ok).is_ok());
    let cases: [(EndpointSpec, ConfigKey, i64); 9] = [
        (EndpointSpec { system_id: 0, ..ok }, ConfigKey::SystemId, 0),
        (
            EndpointSpec {
                component_id: 0,
                ..ok
            },
            ConfigKey::ComponentId,
            0,
        ),
        (
            EndpointSpec {
                link_timeout_ms: 99,
                ..ok
            },
            ConfigKey::LinkTimeout,
            99,
        ),
        (
            EndpointSpec {
                item_timeout_ms: 70_000,
                ..ok
            },
            ConfigKey::ItemTimeout,
            70_000,
        ),
        (
            EndpointSpec {
                item_retries: 21,
                ..ok
            },
            ConfigKey::ItemRetries,
            21,
        ),
        (
            EndpointSpec {
                telemetry_period_ms: 10,
                ..ok
            },
            ConfigKey::TelemetryPeriod,
            10,
        ),
        (
            EndpointSpec {
                counters_period_ms: 60_001,
                ..ok
            },
            ConfigKey::CountersPeriod,
            60_001,
        ),
        (
            EndpointSpec {
                origin_e7: Some((900_000_000, 0)),
                ..ok
            },
            ConfigKey::OriginLatitude,
            900_000_000,
        ),
        (
            EndpointSpec {
                origin_e7: Some((0, -1_800_000_001)),
                ..ok
            },
            ConfigKey::OriginLongitude,
            -1_800_000_001,
        ),
    ];
    for (spec, key, value) in cases {
        let err = EndpointConfig::new(&spec).expect_err("refused");
        assert_eq!((err.key, err.value), (key, value));
        assert!(err.to_string().starts_with(key.key()), "{err}");
    }
    // Telemetry and counters off are allowed.
    assert!(
        EndpointConfig::new(&EndpointSpec {
            telemetry_period_ms: 0,
            counters_period_ms: 0,
            ..ok
        })
        .is_ok()
    );
}

#[test]
fn the_endpoint_fits_in_4_kib_of_ram() {
    // Two missions of 64 items (the running one and the upload's), the
    // parser's 280-byte frame buffer, the counters and timers.
    let size = core::mem::size_of::<wmr_mavlink::MavlinkEndpoint>();
    println!("MavlinkEndpoint: {size} bytes");
    assert!(size <= 4096, "{size}");
}
