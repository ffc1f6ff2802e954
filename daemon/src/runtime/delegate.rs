//! [`delegate_drive_bus!`]: the methods a bus wrapper passes through unchanged.

/// Writes `DriveBus` methods that call the same method of the wrapped bus in field `$inner`,
/// for wrappers that change only some of them (fault injection, tests that record setpoints):
/// `delegate_drive_bus!(inner: name, axes, enable, reset);` inside `impl DriveBus for W`.
/// Methods not named keep the trait's default.
#[macro_export]
macro_rules! delegate_drive_bus {
    ($inner:ident: $($method:ident),+ $(,)?) => {
        $( $crate::delegate_drive_bus!(@one $inner $method); )+
    };
    (@one $i:ident name) => {
        fn name(&self) -> &str {
            self.$i.name()
        }
    };
    (@one $i:ident axes) => {
        fn axes(&self) -> usize {
            self.$i.axes()
        }
    };
    (@one $i:ident has_spindle) => {
        fn has_spindle(&self) -> bool {
            self.$i.has_spindle()
        }
    };
    (@one $i:ident enable) => {
        fn enable(&mut self) {
            self.$i.enable()
        }
    };
    (@one $i:ident reset) => {
        fn reset(&mut self) {
            self.$i.reset()
        }
    };
    (@one $i:ident safe_state) => {
        fn safe_state(&mut self) {
            self.$i.safe_state()
        }
    };
    (@one $i:ident supports_homing) => {
        fn supports_homing(&self) -> bool {
            self.$i.supports_homing()
        }
    };
    (@one $i:ident home_switch) => {
        fn home_switch(&self, axis: usize) -> bool {
            self.$i.home_switch(axis)
        }
    };
    (@one $i:ident enable_timeout_ticks) => {
        fn enable_timeout_ticks(&self) -> u32 {
            self.$i.enable_timeout_ticks()
        }
    };
    (@one $i:ident shutdown) => {
        fn shutdown(&mut self) {
            self.$i.shutdown()
        }
    };
    (@one $i:ident is_shut_down) => {
        fn is_shut_down(&self) -> bool {
            self.$i.is_shut_down()
        }
    };
    (@one $i:ident set_home) => {
        fn set_home(&mut self, axis: usize, trigger_mm: f64, reference_mm: f64) {
            self.$i.set_home(axis, trigger_mm, reference_mm)
        }
    };
}
