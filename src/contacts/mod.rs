//! Contacts between particles: the neighbour search ([`detect`]) and the contact store.

pub mod detect;
