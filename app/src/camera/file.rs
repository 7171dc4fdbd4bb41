//! Frames from files: one still image, or a folder of images played as a sequence.
//!
//! A folder plays its JPEG/PNG files in natural order (`frame2.png` before `frame10.png`) at a
//! fixed frame rate; every frame must have the size of the first. Images are decoded one at a
//! time as frames are asked for.

use super::{Frame, FrameSource};
use crate::scene::background::load_image;
use anyhow::{Context, Result, bail};
use std::cmp::Ordering;
use std::path::{Path, PathBuf};

/// A still image or an image sequence as a [`FrameSource`].
pub struct ImageFiles {
    files: Vec<PathBuf>,
    fps: f64,
    next: usize,
    looping: bool,
    size: Option<(u32, u32)>,
}

impl ImageFiles {
    /// `path`: an image file (one frame) or a folder of images; `fps` sets the timestamps
    /// (frame i is at i / fps seconds).
    pub fn open(path: &Path, fps: f64) -> Result<ImageFiles> {
        if !(fps.is_finite() && fps > 0.0) {
            bail!("frame rate must be a positive number, got {fps}");
        }
        let files = if path.is_dir() {
            let mut files = Vec::new();
            for entry in std::fs::read_dir(path).with_context(|| format!("cannot read image folder {}", path.display()))? {
                let p = entry.with_context(|| format!("cannot read image folder {}", path.display()))?.path();
                let ext = p.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
                if p.is_file() && matches!(ext.as_str(), "jpg" | "jpeg" | "png") {
                    files.push(p);
                }
            }
            if files.is_empty() {
                bail!("image folder {} contains no .jpg or .png files", path.display());
            }
            files.sort_by(|a, b| {
                natural_cmp(&a.file_name().unwrap_or_default().to_string_lossy(), &b.file_name().unwrap_or_default().to_string_lossy())
            });
            files
        } else if path.is_file() {
            vec![path.to_path_buf()]
        } else {
            bail!("{} is neither an image file nor a folder of images", path.display());
        };
        Ok(ImageFiles { files, fps, next: 0, looping: false, size: None })
    }

    /// Start again from the first image after the last (a still image then repeats forever).
    pub fn looping(mut self, on: bool) -> Self {
        self.looping = on;
        self
    }

    /// Number of images in the sequence.
    pub fn len(&self) -> usize {
        self.files.len()
    }

    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }

    /// The image files in playing order.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }
}

impl FrameSource for ImageFiles {
    fn next_frame(&mut self) -> Result<Option<Frame>> {
        let index = if self.looping { self.next % self.files.len() } else { self.next };
        let Some(file) = self.files.get(index) else { return Ok(None) };
        let image = load_image(file)?;
        match self.size {
            None => self.size = Some((image.width, image.height)),
            Some((w, h)) if (w, h) != (image.width, image.height) => {
                bail!("{}: frame is {}x{} but the sequence started at {w}x{h}", file.display(), image.width, image.height)
            }
            Some(_) => {}
        }
        let t = self.next as f64 / self.fps;
        self.next += 1;
        Ok(Some(Frame { image, t }))
    }
}

/// Compare names with digit runs taken as numbers ("f2" < "f10"), otherwise by character.
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (mut a, mut b) = (a.as_bytes(), b.as_bytes());
    loop {
        match (a.first(), b.first()) {
            (None, None) => return Ordering::Equal,
            (None, Some(_)) => return Ordering::Less,
            (Some(_), None) => return Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let da = a.iter().take_while(|c| c.is_ascii_digit()).count();
                let db = b.iter().take_while(|c| c.is_ascii_digit()).count();
                let (na, nb) = (trim_zeros(&a[..da]), trim_zeros(&b[..db]));
                // Longer number (without leading zeros) is larger; equal length compares bytes.
                let ord = na.len().cmp(&nb.len()).then_with(|| na.cmp(nb)).then_with(|| da.cmp(&db));
                if ord != Ordering::Equal {
                    return ord;
                }
                (a, b) = (&a[da..], &b[db..]);
            }
            (Some(x), Some(y)) => {
                if x != y {
                    return x.cmp(y);
                }
                (a, b) = (&a[1..], &b[1..]);
            }
        }
    }
}

fn trim_zeros(digits: &[u8]) -> &[u8] {
    let n = digits.iter().take_while(|&&c| c == b'0').count();
    &digits[n..]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order() {
        let mut names = vec!["f10.png", "f2.png", "f1.png", "f02.png", "a.png", "f.png"];
        names.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(names, vec!["a.png", "f.png", "f1.png", "f2.png", "f02.png", "f10.png"]);
        assert_eq!(natural_cmp("x", "x"), Ordering::Equal);
        assert_eq!(natural_cmp("img_099", "img_100"), Ordering::Less);
    }

    #[test]
    fn sequence_plays_in_order_and_checks_sizes() {
        let dir = std::env::temp_dir().join(format!("previz-seq-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (i, v) in [(1, 10u8), (2, 20), (10, 30)] {
            let img = image::RgbImage::from_pixel(4, 3, image::Rgb([v, v, v]));
            img.save(dir.join(format!("frame{i}.png"))).unwrap();
        }
        std::fs::write(dir.join("notes.txt"), b"ignored").unwrap();
        let mut seq = ImageFiles::open(&dir, 10.0).unwrap();
        assert_eq!(seq.len(), 3);
        let frames: Vec<Frame> = std::iter::from_fn(|| seq.next_frame().unwrap()).collect();
        assert_eq!(frames.iter().map(|f| f.image.pixels[0]).collect::<Vec<_>>(), vec![10, 20, 30]);
        assert_eq!(frames.iter().map(|f| f.t).collect::<Vec<_>>(), vec![0.0, 0.1, 0.2]);
        // Looping a still image repeats it.
        let mut still = ImageFiles::open(&dir.join("frame2.png"), 30.0).unwrap().looping(true);
        for _ in 0..3 {
            assert_eq!(still.next_frame().unwrap().unwrap().image.pixels[0], 20);
        }
        // A frame of another size is an error naming it.
        image::RgbImage::new(5, 3).save(dir.join("frame11.png")).unwrap();
        let mut seq = ImageFiles::open(&dir, 10.0).unwrap();
        for _ in 0..3 {
            seq.next_frame().unwrap();
        }
        let err = seq.next_frame().unwrap_err().to_string();
        assert!(err.contains("frame11.png") && err.contains("5x3"), "{err}");
        // Empty folder, missing path, bad fps.
        let empty = dir.join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        assert!(ImageFiles::open(&empty, 30.0).is_err());
        assert!(ImageFiles::open(&dir.join("nope"), 30.0).is_err());
        assert!(ImageFiles::open(&dir, 0.0).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
