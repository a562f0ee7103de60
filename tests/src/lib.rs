//! Cross-stage and analytic-scene tests of the photon-mapping pipeline. The tests
//! live in `tests/tests/`; this library only holds the helpers they share.
