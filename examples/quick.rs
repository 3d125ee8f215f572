use facemimic::*;
use std::path::Path;
fn main() {
    let t = std::time::Instant::now();
    let list = io::read_list(Path::new("../shared/data/grid/spk07_pwij3p/train20.txt")).unwrap();
    let imgs: Vec<_> = list.iter().map(|p| io::read_training_image(p).unwrap()).collect();
    println!("load {:?}", t.elapsed());
    let t = std::time::Instant::now();
    let m = Builder::default().build(&imgs, None).unwrap();
    println!("build {:?}", t.elapsed());
    println!("frame {}x{} px {} tris {} shape modes {} app modes {}", m.frame.width(), m.frame.height(), m.frame.n_pixels(), m.frame.triangles().len(), m.shape.n_modes(), m.appearance.n_modes());
    println!("shape sig {:?}", m.shape.sigmas());
    let mut r = Renderer::new(&m.frame).unwrap();
    let mut pm = tiny_skia::Pixmap::new(360, 288).unwrap();
    pm.fill(tiny_skia::Color::from_rgba8(40, 40, 40, 255));
    let p = m.project(&imgs[3].image.view().unwrap(), &imgs[3].landmarks).unwrap();
    let t = std::time::Instant::now();
    for _ in 0..100 { r.render(&m, &p, &Similarity::IDENTITY, &mut pm.as_mut()).unwrap(); }
    println!("render {:?}", t.elapsed() / 100);
    io::write_pixmap(Path::new("/tmp/quick.png"), &pm).unwrap();
    io::write_pixmap(Path::new("/tmp/quick_tex.png"), r.texture()).unwrap();
    let mut mean = tiny_skia::Pixmap::new(360, 288).unwrap();
    r.render(&m, &m.base_params(), &Similarity::IDENTITY, &mut mean.as_mut()).unwrap();
    io::write_pixmap(Path::new("/tmp/quick_mean.png"), &mean).unwrap();
}
