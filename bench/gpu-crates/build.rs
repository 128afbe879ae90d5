// intel_tex_2's prebuilt kernels include C++ (its ASTC encoder) that needs
// the C++ runtime, which the crate does not ask the linker for: without
// this line the link fails with an undefined `__gxx_personality_v0`.
fn main() {
    println!("cargo:rustc-link-lib=stdc++");
}
