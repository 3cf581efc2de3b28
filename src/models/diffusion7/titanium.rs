//! The 28 titanium experiments of [IV22] Table 3 (spec §13).
