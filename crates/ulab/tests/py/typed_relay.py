"""Test-only defect peer: a Cyclone DDS 11 *typed* LowState writer (the kind Cyclone DDS 0.10.2 readers crash on).

`ulab sim --unsafe-state-topic rt/lowstate_raw` runs the robot and publishes its LowState on rt/lowstate_raw; this
relay takes those samples with a typed reader (unitree_sdk2py's LowState_) and republishes the very same bytes on
rt/lowstate with a typed writer of Unitree's QoS, so that the only difference from `ulab sim` is the writer's Cyclone 11
XTypes type information. Bytes pass through the binding's C layer untouched (deserialising in Python would cost more
than a core at 500 Hz). Discovery: the unicast settings of ulab's transport (participant index auto, peer 127.0.0.1),
so that 0.10.2 participants on `lo` do discover it.

usage: python typed_relay.py DOMAIN SECONDS
"""
import sys
import time
import types

sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))

from cyclonedds._clayer import ddspy_take, ddspy_write  # noqa: E402
from cyclonedds.core import InstanceState, Policy, Qos, SampleState, ViewState  # noqa: E402
from cyclonedds.domain import Domain, DomainParticipant  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowState_  # noqa: E402

XML = (
    '<CycloneDDS><Domain Id="any"><General><Interfaces><NetworkInterface name="lo" priority="default" '
    'multicast="default"/></Interfaces></General><Discovery><ParticipantIndex>auto</ParticipantIndex>'
    "<MaxAutoParticipantIndex>32</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/></Peers>"
    "</Discovery></Domain></CycloneDDS>"
)


def main():
    domain, seconds = int(sys.argv[1]), float(sys.argv[2])
    if domain == 0:
        sys.exit("refusing domain 0")
    keep = Domain(domain, XML)  # noqa: F841 (the configuration lives as long as this object)
    dp = DomainParticipant(domain)
    reader = DataReader(dp, Topic(dp, "rt/lowstate_raw", LowState_),
                        qos=Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(64)))
    writer = DataWriter(dp, Topic(dp, "rt/lowstate", LowState_),
                        qos=Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(1)))
    mask = SampleState.Any | ViewState.Any | InstanceState.Any
    print("READY", flush=True)
    end = time.time() + seconds
    relayed = 0
    while time.time() < end:
        got = ddspy_take(reader._ref, mask, 64)
        if isinstance(got, int):
            sys.exit(f"take failed: {got}")
        for data, info in got:
            if info.valid_data:
                ddspy_write(writer._ref, data)
                relayed += 1
        if not got:
            time.sleep(0.0005)
    print(f"DONE relayed={relayed}", flush=True)


if __name__ == "__main__":
    main()
