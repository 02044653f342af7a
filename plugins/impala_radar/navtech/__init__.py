"""Navtech radars over their "Colossus" TCP protocol: the protocol (:mod:`.protocol`), the live
driver ``radar.NavtechRadar`` (:mod:`.component`) and the emulator ``impala-flow navtech-server``
(:mod:`.server`)."""
