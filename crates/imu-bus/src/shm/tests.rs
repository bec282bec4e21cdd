//! Tests of service names and instance-name validation.

use super::*;

#[test]
fn service_names_follow_the_documented_scheme() {
    let names = ServiceNames::for_instance("default");
    assert_eq!(names.raw, "imud/default/raw");
    assert_eq!(names.corrected, "imud/default/corrected");
    assert_eq!(names.status, "imud/default/status");
    assert_eq!(names.event, "imud/default/event");
    assert_eq!(names.of(Stream::Corrected), "imud/default/corrected");
}

#[test]
fn options_parse_from_kebab_case_with_defaults_and_reject_unknown_keys() {
    let o: ShmOptions = serde_json::from_str(r#"{"subscriber-buffer-size": 8}"#).unwrap();
    assert_eq!(
        o,
        ShmOptions {
            subscriber_buffer_size: 8,
            ..ShmOptions::default()
        }
    );
    assert!(serde_json::from_str::<ShmOptions>(r#"{"buffer": 8}"#).is_err());
}

#[test]
fn event_ids_are_stable() {
    assert_eq!(ShmEvent::Samples.id(), 1);
    assert_eq!(ShmEvent::Status.id(), 2);
}
