// BoofCV's own calibration of a folder of chessboard images with the unified (Mei-Rives)
// model as BoofCV estimates it (zero skew, two radial coefficients, no tangential terms), for
// benchmarks/bench_boofcv_reference.py (issue 33).  Built and run against the BoofCV jar that
// the PyPI package PyBoof 0.43.1 ships (PyBoof-all.jar); not a dependency of multieye.
//
//   javac -cp PyBoof-all.jar BoofCalibrate.java
//   java -cp PyBoof-all.jar:. BoofCalibrate DIR EXT x|b COUNT CORNERS_OUT
//
// DIR/1EXT ... DIR/COUNT EXT are read; detector x is BoofCV's X-corner chessboard detector
// (its default since 0.32), b the binary (square-polygon) one of earlier versions.  The 5 x 7
// square board of boofcv_fisheye.  Writes one line per detected corner to CORNERS_OUT:
// image, layout index, layout x, layout y, pixel x, pixel y (BoofCV's pixel coordinates), then
// prints the lens on stdout as "lens fx fy cx cy xi k1 k2 t1 t2".
import boofcv.abst.fiducial.calib.ConfigChessboardBinary;
import boofcv.abst.fiducial.calib.ConfigGridDimen;
import boofcv.abst.geo.calibration.CalibrateMonoPlanar;
import boofcv.abst.geo.calibration.DetectSingleFiducialCalibration;
import boofcv.alg.geo.calibration.CalibrationObservation;
import boofcv.factory.fiducial.FactoryFiducialCalibration;
import boofcv.io.image.UtilImageIO;
import boofcv.struct.calib.CameraUniversalOmni;
import boofcv.struct.geo.PointIndex2D_F64;
import boofcv.struct.image.GrayF32;
import georegression.struct.point.Point2D_F64;
import java.io.FileWriter;
import java.io.PrintWriter;
import java.util.Locale;

public class BoofCalibrate {
    public static void main(String[] args) throws Exception {
        String dir = args[0], ext = args[1];
        int count = Integer.parseInt(args[3]);
        ConfigGridDimen grid = new ConfigGridDimen(7, 5, 1.0);
        DetectSingleFiducialCalibration detector = args[2].equals("b")
                ? FactoryFiducialCalibration.chessboardB(new ConfigChessboardBinary(), grid)
                : FactoryFiducialCalibration.chessboardX(null, grid);
        CalibrateMonoPlanar calib = new CalibrateMonoPlanar();
        GrayF32 first = null;
        try (PrintWriter out = new PrintWriter(new FileWriter(args[4]))) {
            for (int k = 1; k <= count; k++) {
                GrayF32 image = UtilImageIO.loadImage(dir + "/" + k + ext, GrayF32.class);
                if (image == null) continue;
                if (first == null) {
                    first = image;
                    calib.initialize(image.width, image.height, detector.getLayout());
                    calib.configureUniversalOmni(true, 2, false);
                }
                if (!detector.process(image)) continue;
                CalibrationObservation obs = detector.getDetectedPoints().copy();
                calib.addImage(obs);
                for (PointIndex2D_F64 p : obs.points) {
                    Point2D_F64 l = detector.getLayout().get(p.index);
                    out.printf(Locale.ROOT, "%d %d %.6f %.6f %.6f %.6f%n", k, p.index, l.x, l.y,
                               p.p.x, p.p.y);
                }
            }
        }
        CameraUniversalOmni lens = calib.process();
        System.out.printf(Locale.ROOT, "lens %.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f%n",
                          lens.fx, lens.fy, lens.cx, lens.cy, lens.mirrorOffset, lens.radial[0],
                          lens.radial[1], lens.t1, lens.t2);
    }
}
