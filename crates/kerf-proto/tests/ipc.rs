//! Smoke test: the messages go through real iceoryx2 services in-process and arrive equal.
//! The services are `ipc::Service` (shared memory, as between `kerf run` and the daemon),
//! each with a name unique to this process and test.

use std::sync::atomic::{AtomicU32, Ordering};

use iceoryx2::prelude::*;
use kerf_gcode::{Dialect, Interpreter, Item, Settings};
use kerf_proto::{
    ControlCommand, MoveMsg, REASON_OK, Request, Resolved, Response, STATE_RUNNING, SetpointMsg,
    StatusMsg, StreamCheck,
};

static COUNTER: AtomicU32 = AtomicU32::new(0);

/// A service name no other test or process uses: kerf/test-<pid>-<n>/<which>.
fn unique(which: &str) -> ServiceName {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let machine = format!("test-{}-{n}", std::process::id());
    let name = kerf_proto::service_name(&machine, which).expect("valid machine name");
    ServiceName::new(&name).expect("valid iceoryx2 service name")
}

#[test]
fn a_program_goes_through_publish_subscribe() {
    let program = "G21 G90 F600\nG1 X10\nG3 X0 Y10 I-10 J0 Z-1\nM3 S1000\nM30\n";
    let items: Vec<Item> =
        Interpreter::new(program.as_bytes(), Dialect::LinuxCnc, Settings::default())
            .collect::<Result<_, _>>()
            .expect("valid program");
    let mut sent = vec![MoveMsg::begin(11, [0.0; 6], items.len() as u64)];
    sent.extend(
        items
            .iter()
            .enumerate()
            .map(|(i, it)| MoveMsg::from_item(11, i as u64 + 1, it)),
    );
    sent.push(MoveMsg::end(11, items.len() as u64));

    let node = NodeBuilder::new().create::<ipc::Service>().expect("node");
    let service = node
        .service_builder(&unique(kerf_proto::SERVICE_MOVES))
        .publish_subscribe::<MoveMsg>()
        .subscriber_max_buffer_size(16)
        .history_size(0)
        .open_or_create()
        .expect("service");
    let subscriber = service
        .subscriber_builder()
        .buffer_size(16)
        .create()
        .expect("subscriber");
    let publisher = service.publisher_builder().create().expect("publisher");
    for m in &sent {
        publisher
            .loan_uninit()
            .expect("loan")
            .write_payload(*m)
            .send()
            .expect("send");
    }
    let mut received = Vec::new();
    while let Some(sample) = subscriber.receive().expect("receive") {
        received.push(*sample);
    }
    assert_eq!(received, sent);

    // And the daemon side accepts it, decoding the same items.
    let mut check = StreamCheck::new();
    let decoded: Vec<Resolved> = received
        .iter()
        .map(|m| check.check(m).expect("valid"))
        .collect();
    for (item, r) in items.iter().zip(&decoded[1..]) {
        match (item, r) {
            (Item::Move(a), Resolved::Move(b)) => assert_eq!(a, b),
            (Item::Event(a), Resolved::Event(b)) => assert_eq!(a, b),
            (a, b) => panic!("{a:?} arrived as {b:?}"),
        }
    }
}

#[test]
fn setpoints_go_through_publish_subscribe() {
    let node = NodeBuilder::new().create::<ipc::Service>().expect("node");
    let service = node
        .service_builder(&unique(kerf_proto::SERVICE_SETPOINTS))
        .publish_subscribe::<SetpointMsg>()
        .open_or_create()
        .expect("service");
    let subscriber = service.subscriber_builder().create().expect("subscriber");
    let publisher = service.publisher_builder().create().expect("publisher");
    let mut sp = SetpointMsg::new();
    sp.seq = 12345;
    sp.state = STATE_RUNNING;
    sp.position_mm_deg = [1.5, -2.0, 3.25, 0.0, 90.0, 0.0];
    sp.axes_mask = 0b1_0111;
    publisher.send_copy(sp).expect("send");
    let got = *subscriber.receive().expect("receive").expect("a sample");
    assert_eq!(got, sp);
}

#[test]
fn control_goes_through_request_response() {
    let node = NodeBuilder::new().create::<ipc::Service>().expect("node");
    let service = node
        .service_builder(&unique(kerf_proto::SERVICE_CONTROL))
        .request_response::<Request, Response>()
        .open_or_create()
        .expect("service");
    let server = service.server_builder().create().expect("server");
    let client = service.client_builder().create().expect("client");

    let request = Request::from_command(ControlCommand::Override { percent: 120.0 }, 77);
    let pending = client.send_copy(request).expect("send request");

    let active = server.receive().expect("receive").expect("a request");
    assert_eq!(*active, request);
    assert_eq!(
        active.command(),
        Ok(ControlCommand::Override { percent: 120.0 })
    );
    let mut status = StatusMsg::zeroed();
    status.override_pct = 120.0;
    status.set_fault_text("none");
    let response = Response::new(active.id, REASON_OK, "override 120 %", status);
    active.send_copy(response).expect("send response");
    drop(active);

    let got = *pending.receive().expect("receive").expect("a response");
    assert_eq!(got, response);
    assert_eq!(got.message(), "override 120 %");
    assert_eq!(got.status.fault_text(), "none");
}
