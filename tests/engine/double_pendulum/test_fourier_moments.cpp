// SPDX-License-Identifier: GPL-3.0-or-later
// q_power_moments (engine/double_pendulum/fourier_moments.hpp): Fourier moments of q(t)^s,
// s = 1/2, -1/2, -3/2,
// q = mu1 + mu2 sin^2 t, against references computed independently of the header's method:
//  * 147 values pasted from mpmath (hyp2f1 form at 80 digits, cross-checked against
//    mpmath.quad and mpmath.legenp; generator below);
//  * a dense high-precision reference for all k built inside the test from the plain
//    three-term recurrence (Miller's backward algorithm where its start index is affordable,
//    forward recursion from the closed forms of Q_0, Q_1 with enough extra digits otherwise),
//    normalised with K, E from the arithmetic-geometric mean.
// Errors are measured as max_k |Q_k - exact| / max_k |Q_k| per row (max_k |Q_k| = Q_0 since
// q^s > 0), and the reported relative_error must cover them.
#include <catch2/catch.hpp>

#include "engine/double_pendulum/fourier_moments.hpp"
#include "engine/numerics/precision.hpp"

#include <boost/math/constants/constants.hpp>

#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

using pendavg::mpfr_real;
using pendavg::detail::q_power_moments;

namespace {

// Generated with (python3, mpmath 1.2.1) -- run as `python3 gen_ref2.py check` to also print
// the cross-checks to stderr (all agreed to <= 1e-44 relative, or relative to Q_0 for quad):
//   # Reference values for tests/engine/double_pendulum/test_fourier_moments.cpp.
//   # Q_k(s) = int_0^{pi/2} (mu1 + mu2 sin^2 t)^s cos(2kt) dt, mu2 = 1 - mu1 exactly, mu1 = the
//   # binary double nearest the listed decimal (mpf(float) is exact).
//   # Value: (pi/2) C^s r^k (-s)_k/k! 2F1(-s, k-s; k+1; r^2), C = ((1+sqrt mu1)/2)^2,
//   # r = (1-sqrt mu1)/(1+sqrt mu1), by mpmath's hyp2f1 at 80 digits; cross-checked (stderr)
//   # against mpmath.quad (k <= 49, error relative to Q_0) and mpmath.legenp type 3.
//   import sys
//   from mpmath import mp, mpf, hyp2f1, legenp, gamma, pi, sqrt, quad, sin, cos, nstr, rf, factorial, fabs
//   mp.dps = 80
//   MU = [0.5, 0.1, 1e-2, 1e-4, 1e-8, 1e-12, 0.999999]
//   KS = [0, 1, 2, 7, 49, 399, 2999]
//   SS = [mpf(1)/2, -mpf(1)/2, -mpf(3)/2]
//   def hyp(mu1, s, k):
//       rm = sqrt(mu1); r = (1 - rm)/(1 + rm); C = ((1 + rm)/2)**2
//       return pi/2 * C**s * r**k * rf(-s, k)/factorial(k) * hyp2f1(-s, k - s, k + 1, r*r)
//   def closed(mu1, s, k):
//       z = (1 + mu1) / (2 * sqrt(mu1))
//       return pi/2 * mu1**(s/2) * (-1)**k * gamma(s+1)/gamma(s+k+1) * legenp(s, k, z, type=3)
//   def byquad(mu1, s, k):
//       mu2 = 1 - mu1
//       f = lambda t: (mu1 + mu2*sin(t)**2)**s * cos(2*k*t)
//       e = sqrt(mu1)
//       pts = [mpf(0)] + [e*4**i for i in range(0, 40) if e*4**i < pi/2] + [pi/2]
//       fine = [pts[0]]
//       for a, b in zip(pts[:-1], pts[1:]):
//           n = int((b - a) * k / 1.0) + 1
//           fine += [a + (b - a) * j / n for j in range(1, n + 1)]
//       with mp.workdps(45):
//           return quad(f, fine)
//   check = len(sys.argv) > 1
//   for m in MU:
//       mu1 = mpf(m)
//       for si, s in enumerate(SS):
//           q0 = hyp(mu1, s, 0)
//           for k in KS:
//               v = hyp(mu1, s, k)
//               if check:
//                   msg = "#check %s %s %d" % (m, float(s), k)
//                   if k <= 49:
//                       msg += " quad/Q0 %s" % nstr((byquad(mu1, s, k) - v) / q0, 3)
//                   try:
//                       with mp.workdps(60):
//                           msg += " legenp %s" % nstr((closed(mu1, s, k) - v) / v, 3)
//                   except Exception:
//                       msg += " legenp failed"
//                   print(msg, file=sys.stderr)
//               print('    {%s, %d, %d, "%s"},' % (repr(m), si, k, nstr(v, 40, min_fixed=0, max_fixed=0)))
struct MpmathRef {
  double mu1;
  int row;  // 0: s = 1/2, 1: s = -1/2, 2: s = -3/2
  int k;
  const char* value;
};
const MpmathRef kMpmath[] = {
    {0.5, 0, 0, "1.35064388104767550252017473533872584135"},
    {0.5, 0, 1, "-1.145940961800942235642745038752191438711e-1"},
    {0.5, 0, 2, "-4.897054622691036050223862232780777020791e-3"},
    {0.5, 0, 7, "-9.341515340806218426231407826320840359439e-8"},
    {0.5, 0, 49, "-3.368915314226324723631354504914571596466e-41"},
    {0.5, 0, 399, "-1.641475525530964490521252457822208216142e-310"},
    {0.5, 0, 2999, "-2.93284894161800369022315659288809643467e-2302"},
    {0.5, 1, 0, "1.854074677301371918433850347195260046218"},
    {0.5, 1, 1, "1.596485077134137452208521002308767732547e-1"},
    {0.5, 1, 2, "2.056913841986434140545828519175374427963e-2"},
    {0.5, 1, 7, "1.710940265949409549954209632626479016508e-6"},
    {0.5, 1, 49, "4.618633908567583013319104021559426402681e-39"},
    {0.5, 1, 399, "1.850013097213245299313282033828819813522e-307"},
    {0.5, 1, 2999, "2.487335400446708396581282519548411451685e-2298"},
    {0.5, 2, 0, "2.701287762095351005040349470677451682699"},
    {0.5, 2, 1, "6.875645770805653413856470232513148632267e-1"},
    {0.5, 2, 2, "1.469116386807310815067158669834233106237e-1"},
    {0.5, 2, 7, "3.643190982914425186230249052265127740181e-5"},
    {0.5, 2, 49, "6.470338752503079264206379462138926208173e-37"},
    {0.5, 2, 399, "2.090593078169389560914810257797111317327e-304"},
    {0.5, 2, 2999, "2.110243646443922512269587045104238719959e-2294"},
    {0.1, 0, 0, "1.104774732704073330634040196512765982989"},
    {0.1, 0, 1, "-2.591236234462392641134697054916055442822e-1"},
    {0.1, 0, 2, "-3.241037416217483940325135643061061442078e-2"},
    {0.1, 0, 7, "-1.502484028000601865828632016893533083013e-4"},
    {0.1, 0, 49, "-8.519185571753959518056922501548244504916e-18"},
    {0.1, 0, 399, "-1.028844485491921397408587461839399703431e-118"},
    {0.1, 0, 2999, "-1.609919616372396007209966240747400976754e-859"},
    {0.1, 1, 0, "2.578092113348173162082553469377671983794"},
    {0.1, 1, 1, "6.959465103053820391081041563900893679583e-1"},
    {0.1, 1, 2, "2.747710160482685779783776687454307515722e-1"},
    {0.1, 1, 7, "5.908571332626032424399815585540228841822e-3"},
    {0.1, 1, 49, "2.594074013458523781060139525918099328918e-15"},
    {0.1, 1, 399, "2.590640247634617391645722630186864473578e-115"},
    {0.1, 1, 2999, "3.052704301825304857510784228107866189631e-855"},
    {0.1, 2, 0, "1.104774732704073269306722932904512382389e+1"},
    {0.1, 2, 1, "7.773708703387177491876571703277362472139"},
    {0.1, 2, 2, "4.861556124326225640617126227870802113548"},
    {0.1, 2, 7, "2.929843854601173475726827136205280597178e-1"},
    {0.1, 2, 49, "8.180973904555326871054783043492193320135e-13"},
    {0.1, 2, 399, "6.551712548947119852646701086283884001155e-112"},
    {0.1, 2, 2999, "5.791847294837216465745265618642458485956e-851"},
    {0.01, 0, 0, "1.015993545025223935921171974585074788469"},
    {0.01, 0, 1, "-3.206197754934945053209264248352784995575e-1"},
    {0.01, 0, 2, "-5.847884513510022332806363877867304443618e-2"},
    {0.01, 0, 7, "-2.297604418727802430225523094959928017064e-3"},
    {0.01, 0, 49, "-2.274603936443986726593290780865071489538e-8"},
    {0.01, 0, 399, "-2.979783438943974647205284497202603006852e-40"},
    {0.01, 0, 2999, "-3.697832964993375443972311841018935093919e-268"},
    {0.01, 1, 0, "3.695637362989874667516870770575281001429"},
    {0.01, 1, 1, "1.717784491484167215632919521484370714287"},
    {0.01, 1, 2, "1.104770490315171593671674902755726992549"},
    {0.01, 1, 7, "2.421815074209862855960565165565821107377e-1"},
    {0.01, 1, 49, "2.121996704038081692428286427107674916607e-5"},
    {0.01, 1, 399, "2.362954809763081169828165882827088272351e-36"},
    {0.01, 1, 2999, "2.216095068857591725722154050322855553003e-263"},
    {0.01, 2, 0, "1.015993545025223914771557726631213651553e+2"},
    {0.01, 2, 1, "9.61859326480483495940059823710617134396e+1"},
    {0.01, 2, 2, "8.771826770265033316609219909834142031909e+1"},
    {0.01, 2, 7, "4.480328616519214645674195261173005085345e+1"},
    {0.01, 2, 49, "2.184302160167160408077614306438828986923e-2"},
    {0.01, 2, 399, "1.897535033269839847763883959252634692977e-32"},
    {0.01, 2, 2999, "1.33033249842100567183163403670476098693e-258"},
    {0.0001, 0, 0, "1.000274582430662965198826943521310982782"},
    {0.0001, 0, 1, "-3.330920732142563030209100722625206469304e-1"},
    {0.0001, 0, 2, "-6.64720421469929024333058805262813359856e-2"},
    {0.0001, 0, 7, "-4.998477251685182637710857086462656702984e-3"},
    {0.0001, 0, 49, "-6.355943629585651888985684683431493859368e-5"},
    {0.0001, 0, 399, "-1.988493272499290390843501729559805907597e-9"},
    {0.0001, 0, 2999, "-2.420427545253814208938528176290689175763e-33"},
    {0.0001, 1, 0, "5.991589340506996378398022361383720986716"},
    {0.0001, 1, 1, "3.992038538433564504136465201074848063143"},
    {0.0001, 1, 2, "3.326586254484343688949025726180920736285"},
    {0.0001, 1, 7, "2.096344613591268805692495311705522808586"},
    {0.0001, 1, 49, "4.332464664862306536138751271907139446974e-1"},
    {0.0001, 1, 399, "1.495714518517109185456090482040773321659e-4"},
    {0.0001, 1, 2999, "1.439817921575687677575196584506477321731e-27"},
    {0.0001, 2, 0, "1.000274582430662917263932452902997030055e+4"},
    {0.0001, 2, 1, "9.992762196427688611756790041467511731503e+3"},
    {0.0001, 2, 2, "9.970806322048934887177533568685744425105e+3"},
    {0.0001, 2, 7, "9.747030640786105676441541934382302861138e+3"},
    {0.0001, 2, 49, "6.103612667491101216497237958107027506843e+3"},
    {0.0001, 2, 399, "1.266278481407365558078051313191679266701e+1"},
    {0.0001, 2, 2999, "8.707730862933385156931931868275639188963e-22"},
    {1e-08, 0, 0, "1.000000050483173843854770125182543589651"},
    {1e-08, 0, 1, "-3.333332861834925974793587588340973386161e-1"},
    {1e-08, 0, 2, "-6.666662418349194148174097597956565975788e-2"},
    {1e-08, 0, 7, "-5.128169170718148749512958936494516193259e-3"},
    {1e-08, 0, 49, "-1.041079174370194521805428059341425484821e-4"},
    {1e-08, 0, 399, "-1.55460803435967362171016168183768709053e-6"},
    {1e-08, 0, 2999, "-2.17309929689742904599128973870889022537e-8"},
    {1e-08, 1, 0, "1.059663475708766030979426035821632902405e+1"},
    {1e-08, 1, 1, "8.596634848054008673501413956531493418554"},
    {1e-08, 1, 2, "7.929968440953056368613350317799567781149"},
    {1e-08, 1, 7, "6.686371003364943208400506912338461463922"},
    {1e-08, 1, 49, "4.741424914904346824801671811712674838326"},
    {1e-08, 1, 399, "2.64996720294348738506460269211293924494"},
    {1e-08, 1, 2999, "7.77782712952565573027751528928565855922e-1"},
    {1e-08, 2, 0, "1.000000050483173822932208238816795706076e+8"},
    {1e-08, 2, 1, "9.999998585504777715155184058600525585977e+7"},
    {1e-08, 2, 2, "9.999993627523791013035671424171243286659e+7"},
    {1e-08, 2, 7, "9.999929882900389852326128654161405315713e+7"},
    {1e-08, 2, 49, "9.997483311476977783724572921284400678639e+7"},
    {1e-08, 2, 399, "9.899790601043432206129989838927522134683e+7"},
    {1e-08, 2, 2999, "7.817942682447979641515596421390405715283e+7"},
    {1e-12, 0, 0, "1.000000000007350902459544729432070583088"},
    {1e-12, 0, 1, "-3.333333333263157642071185326099951907832e-1"},
    {1e-12, 0, 2, "-6.666666666011576420710851874691962703548e-2"},
    {1e-12, 0, 7, "-5.12820512230679539800010193744414139276e-3"},
    {1e-12, 0, 49, "-1.041341198294007591196227591310037901469e-4"},
    {1e-12, 0, 399, "-1.570340486147152421898243320604623291028e-6"},
    {1e-12, 0, 2999, "-2.779344018736299385732106740143535641403e-8"},
    {1e-12, 1, 0, "1.520180491908771518422886217119788584247e+1"},
    {1e-12, 1, 1, "1.320180491910141698914796184393582968703e+1"},
    {1e-12, 1, 2, "1.253513825247452240390530071759123636107e+1"},
    {1e-12, 1, 7, "1.129153740942151268288123309769286673113e+1"},
    {1e-12, 1, 49, "9.34645726718029993978263865544923436688"},
    {1e-12, 1, 399, "7.249334527753231199319239652146921679443"},
    {1e-12, 1, 2999, "5.232316762777274647272512375207192352622"},
    {1e-12, 2, 0, "1.000000000007350922572897100324306911794e+12"},
    {1e-12, 2, 1, "9.999999999789473127347079681509300877788e+11"},
    {1e-12, 2, 2, "9.999999999017364832199801499717703000943e+11"},
    {1e-12, 2, 7, "9.999999988498251227233722254121196096929e+11"},
    {1e-12, 2, 49, "9.999999527217355099390887757550208636808e+11"},
    {1e-12, 2, 399, "9.999975325999651238353697843490295070604e+11"},
    {1e-12, 2, 2999, "9.998968875608916492112427267200320360652e+11"},
    {0.999999, 0, 0, "1.570795934095741278106341456718127030706"},
    {0.999999, 0, 1, "-1.963495899424164638173343083824868111062e-7"},
    {0.999999, 0, 2, "-1.227185550768233930714688752162087683852e-14"},
    {0.999999, 0, 7, "-1.544846512761932689813759266040037847753e-48"},
    {0.999999, 0, 49, "-4.108073911567223678421778864910663402689e-327"},
    {0.999999, 0, 399, "-3.33898226760343525347562841223855248129e-2639"},
    {0.999999, 0, 2999, "-7.142359705523280645751473884575451395293e-19806"},
    {0.999999, 1, 0, "1.570796719494199222634665981070727404803"},
    {0.999999, 1, 1, "1.963496881172789330723496752266368098728e-7"},
    {0.999999, 1, 2, "3.681558493084331883110971239066226559021e-14"},
    {0.999999, 1, 7, "2.008301470741483244320820916933213799761e-47"},
    {0.999999, 1, 49, "3.984833686637543467549441091266139556827e-325"},
    {0.999999, 1, 399, "2.661170197865369098599508058456627243689e-2636"},
    {0.999999, 1, 2999, "4.283275257040475305518944720544191731036e-19802"},
    {0.999999, 2, 0, "1.570797504893246216521884052214073917646"},
    {0.999999, 2, 1, "5.890493588766082849987936712862055437598e-7"},
    {0.999999, 2, 2, "1.840780166932517881522771579421545094212e-13"},
    {0.999999, 2, 7, "3.01245371233948117124311013453749287204e-46"},
    {0.999999, 2, 49, "3.944987322265327277156443360185394983719e-323"},
    {0.999999, 2, 399, "2.126276051232721673583194981096286150467e-2633"},
    {0.999999, 2, 2999, "2.5695381114679581526608981731488975476e-19798"},
};

const double kMu1[] = {0.5, 0.1, 1e-2, 1e-4, 1e-8, 1e-12, 0.999999};
const std::size_t kCounts[] = {1, 2, 50, 400, 3000};
constexpr std::size_t kMaxCount = 3000;
constexpr int kRefDigits = 50;

// K(k), E(k), k^2 = 1 - mu1, by the AGM (DLMF 19.8.1, 19.8.6) at the current precision.
void agm_elliptic(const mpfr_real& mu1, mpfr_real& K, mpfr_real& E) {
  mpfr_real a = 1, b = sqrt(mu1), c = sqrt(1 - mu1);
  mpfr_real sum = c * c / 2, pow2 = 1;  // sum_{n>=0} 2^{n-1} c_n^2
  const mpfr_real eps = pow(mpfr_real(10), -static_cast<int>(mpfr_real::thread_default_precision()) - 5);
  for (int n = 1; n < 200 && abs(c) > eps * a; ++n) {
    const mpfr_real an = (a + b) / 2;
    c = (a - b) / 2;
    b = sqrt(a * b);
    a = an;
    sum += pow2 * c * c;
    pow2 *= 2;
  }
  K = boost::math::constants::pi<mpfr_real>() / (2 * a);
  E = K * (1 - sum);
}

// Dense reference Q_k(s), k < kMaxCount, for the exact inputs mu1 (a double) and 1 - mu1.
struct DenseRef {
  std::array<std::vector<mpfr_real>, 3> Q;
};

DenseRef make_dense_reference(double m) {
  const double s_of[3] = {0.5, -0.5, -1.5};
  const std::size_t K = kMaxCount;
  const double d = std::atanh(std::sqrt(m));
  const double miller_extra = (kRefDigits + 8) * std::log(10.0) / (4 * d) + 20;
  const bool miller = miller_extra < 60000;
  const int digits =
      miller ? kRefDigits + 10
             : kRefDigits + 10 + static_cast<int>(2 * std::log10(double(K)) + 4 * K * d / std::log(10.0));
  pendavg::working_precision guard(digits);
  const mpfr_real mu1 = m;  // exact
  const mpfr_real mu2 = 1 - mu1;
  const mpfr_real A = 2 * (1 + mu1) / mu2;
  mpfr_real Kell, Eell;
  agm_elliptic(mu1, Kell, Eell);
  const mpfr_real q0[3] = {Eell, Kell, Eell / mu1};
  DenseRef ref;
  for (int row = 0; row < 3; ++row) {
    const mpfr_real s = s_of[row];
    auto& q = ref.Q[row];
    q.assign(K, mpfr_real(0));
    if (miller) {
      // (k-1-s) Q_{k-1} = A k Q_k - (k+1+s) Q_{k+1}, from Q_{N+1} = 0, Q_N = 1
      const std::size_t N = K + static_cast<std::size_t>(miller_extra);
      mpfr_real hi = 0, cur = 1;
      for (std::size_t k = N; k >= 1; --k) {
        const mpfr_real kk = static_cast<double>(k);
        const mpfr_real lo = (A * kk * cur - (kk + 1 + s) * hi) / (kk - 1 - s);
        hi = cur;
        cur = lo;
        if (k - 1 < K) q[k - 1] = cur;
      }
      const mpfr_real f = q0[row] / q[0];
      for (auto& v : q) v *= f;
    } else {
      // Q_1(s) = ((1+mu1) Q_0(s) - 2 Q_0(s+1)) / mu2, Q_0(3/2) = (2(1+mu1)E - mu1 K)/3
      const mpfr_real q0_next[3] = {(2 * (1 + mu1) * Eell - mu1 * Kell) / 3, Eell, Kell};
      q[0] = q0[row];
      q[1] = ((1 + mu1) * q0[row] - 2 * q0_next[row]) / mu2;
      for (std::size_t k = 1; k + 1 < K; ++k) {
        const mpfr_real kk = static_cast<double>(k);
        q[k + 1] = (A * kk * q[k] - (kk - 1 - s) * q[k - 1]) / (kk + 1 + s);
      }
    }
  }
  return ref;
}

const DenseRef& dense_reference(double m) {
  static std::vector<std::pair<double, DenseRef>> cache;
  for (auto& [mm, r] : cache)
    if (mm == m) return r;
  cache.emplace_back(m, make_dense_reference(m));
  return cache.back().second;
}

// max over rows of max_k |Q_k - ref_k| / ref_0
template <class Real>
double max_error(const pendavg::detail::QPowerMoments<Real>& res, const DenseRef& ref,
                 std::size_t count) {
  pendavg::working_precision guard(kRefDigits + 10);
  double worst = 0;
  for (int row = 0; row < 3; ++row) {
    REQUIRE(res.Q[row].size() == count);
    const mpfr_real scale = abs(ref.Q[row][0]);
    for (std::size_t k = 0; k < count; ++k) {
      const mpfr_real diff = abs(mpfr_real(res.Q[row][k]) - ref.Q[row][k]) / scale;
      worst = std::max(worst, static_cast<double>(diff));
    }
  }
  return worst;
}

}  // namespace

TEST_CASE("dense reference agrees with the mpmath values", "[moments]") {
  pendavg::working_precision guard(kRefDigits + 10);
  for (const auto& r : kMpmath) {
    const auto& ref = dense_reference(r.mu1);
    const mpfr_real v(r.value);
    const double err = static_cast<double>(abs(ref.Q[r.row][r.k] - v) / abs(ref.Q[r.row][0]));
    INFO("mu1 = " << r.mu1 << ", row " << r.row << ", k = " << r.k);
    CHECK(err < 1e-38);
  }
}

TEST_CASE("mpfr at 40 digits matches the mpmath values", "[moments]") {
  pendavg::working_precision guard(40);
  for (double m : kMu1) {
    const mpfr_real mu1 = m;
    const mpfr_real mu2 = 1 - mu1;
    const auto res = q_power_moments(mu1, mu2, kMaxCount);
    for (const auto& r : kMpmath) {
      if (r.mu1 != m) continue;
      const mpfr_real v(r.value);
      const double err = static_cast<double>(abs(res.Q[r.row][r.k] - v) / abs(res.Q[r.row][0]));
      INFO("mu1 = " << m << ", row " << r.row << ", k = " << r.k << ": error " << err
                    << ", bound " << static_cast<double>(res.relative_error));
      CHECK(err < 1e-37);
      // the pasted values carry 40 significant digits (+-5e-40 relative)
      CHECK(err <= static_cast<double>(res.relative_error) + 1e-39);
    }
  }
}

TEMPLATE_TEST_CASE("double and long double: <= 64 ulps of max|Q|, error bound covers", "[moments]",
                   double, long double) {
  using Real = TestType;
  const double eps = std::numeric_limits<Real>::epsilon();
  for (double m : kMu1) {
    const auto& ref = dense_reference(m);
    const Real mu1 = static_cast<Real>(m);
    const Real mu2 = 1 - mu1;  // rounded, as a caller would pass it
    for (std::size_t count : kCounts) {
      const auto res = q_power_moments(mu1, mu2, count);
      const double err = max_error(res, ref, count);
      const double bound = static_cast<double>(res.relative_error);
      INFO("mu1 = " << m << ", count = " << count << ": error " << err / eps << " ulps, bound "
                    << bound / eps << " ulps");
      CHECK(err <= 64 * eps);
      CHECK(err <= bound);
      CHECK(bound <= 256 * eps);  // the bound is informative, not just safe
    }
  }
}

TEST_CASE("mpfr at 30 digits: <= 64 ulps of max|Q|, error bound covers", "[moments]") {
  for (double m : kMu1) {
    const auto& ref = dense_reference(m);
    for (std::size_t count : kCounts) {
      pendavg::working_precision guard(30);
      const double u = static_cast<double>(pendavg::unit_roundoff<mpfr_real>());
      const mpfr_real mu1 = m;
      const mpfr_real mu2 = 1 - mu1;
      const auto res = q_power_moments(mu1, mu2, count);
      for (const auto& row : res.Q)
        for (const auto& v : row) REQUIRE(v.precision() == 30);
      const double err = max_error(res, ref, count);
      const double bound = static_cast<double>(res.relative_error);
      INFO("mu1 = " << m << ", count = " << count << ": error " << err / u << " u, bound "
                    << bound / u << " u");
      CHECK(err <= 64 * u);
      CHECK(err <= bound);
      CHECK(bound <= 256 * u);
    }
  }
}

TEST_CASE("exact identities and edge cases", "[moments]") {
  // Q_0 is E, K, E/mu1; Q_k(-3/2) = -(4k^2-1)/mu1 Q_k(1/2); count 0 gives empty rows.
  const double m = 1e-3;
  const auto res = q_power_moments(m, 1 - m, 10);
  const auto ell = pendavg::detail::complete_elliptic_from_complement(m);
  CHECK(res.Q[0][0] == Approx(ell.E).epsilon(4e-16));
  CHECK(res.Q[1][0] == Approx(ell.K).epsilon(4e-16));
  CHECK(res.Q[2][0] == Approx(ell.E / m).epsilon(4e-16));
  for (std::size_t k = 1; k < 10; ++k) {
    const double kk = static_cast<double>(k);
    CHECK(res.Q[2][k] == Approx(-(4 * kk * kk - 1) / m * res.Q[0][k]).epsilon(8e-16));
  }
  const auto empty = q_power_moments(0.25, 0.75, 0);
  for (const auto& row : empty.Q) CHECK(row.empty());
  CHECK_THROWS(q_power_moments(0.0, 1.0, 5));
  // tiny mu1 and mu2: no overflow, rows decay to exact zeros rather than garbage
  const auto tiny = q_power_moments(1e-300, 1.0, 50);
  for (const auto& row : tiny.Q)
    for (double v : row) CHECK(std::isfinite(v));
  const auto flat = q_power_moments(1 - 1e-15, 1e-15, 3000);
  for (const auto& row : flat.Q)
    for (double v : row) CHECK(std::isfinite(v));
  CHECK(flat.Q[1][2999] == 0.0);
}

// digamma_minus_log (psi(x) - ln x, the base brackets of series_top): the closed forms at
// integers and half-integers (series_top's psi(K + 1/2)), the recurrence + asymptotic series
// elsewhere below x0, the series alone above it; against MPFR's correctly rounded mpfr_digamma
// at 40 more digits. Allowed: a few units of the working precision times the cancellation of
// psi(x) - ln x (|psi(x)| / |psi(x) - ln x| <= ~2 x ln x).
TEST_CASE("digamma minus log: closed forms, recurrence and series against mpfr_digamma",
          "[moments][digamma]") {
  using pendavg::detail::fourier_moments_impl::digamma_minus_log;
  using pendavg::detail::fourier_moments_impl::unit_roundoff_of;
  for (const int digits : {30, 60, 110}) {
    pendavg::working_precision guard(digits);
    const mpfr_real u = unit_roundoff_of<mpfr_real>();
    for (const double x : {1.0, 1.5, 2.0, 2.5, 7.0, 7.5, 20.5, 40.5, 41.5, 63.5, 120.5, 1000.5,
                           1.37, 2.371, 10.713, 31.29, 61.77, 250.25}) {
      const mpfr_real xr(x);
      const mpfr_real got = digamma_minus_log(xr, u);
      mpfr_real exact;
      {
        pendavg::working_precision wide(digits + 40);
        mpfr_real psi, xw(x);
        mpfr_digamma(psi.backend().data(), xw.backend().data(), MPFR_RNDN);
        exact = psi - log(xw);
      }
      const double cancellation = std::max(1.0, 2 * x * std::max(1.0, std::log(x)));
      const mpfr_real relative = abs(got - exact) / abs(exact);
      INFO("digits " << digits << " x = " << x << " relative error " << relative);
      CHECK(relative <= 16 * cancellation * u);
      // The closed forms (2x an integer, below the series' threshold x0) are formed with guard
      // bits and rounded once.
      const double x0 = 1.2 * -std::log(static_cast<double>(u)) / (2 * 3.141592653589793) + 2.0;
      if (2 * x == std::floor(2 * x) && x < x0) CHECK(relative <= 2 * u);
    }
  }
}

TEST_CASE("the moments' decay bound behind the N = 2 sums' row cut: |Q_k(s)| <= (k+1) r^k Q_0(s)",
          "[moments]") {
  // engine/double_pendulum/integral.cpp (moment_sum_terms) stops the exact sums' rows where this bound,
  // r = (1 - sqrt mu1)/(1 + sqrt mu1), makes the tail negligible; for s = -1/2 the sharper
  // Q_k / Q_{k-1} <= r holds as well (its Fourier coefficients are positive sums).
  pendavg::working_precision guard(40);
  for (const double m1 : {1e-6, 1e-2, 0.3, 0.5, 0.9, 0.999}) {
    const mpfr_real mu1 = m1, mu2 = 1 - mu1;
    const std::size_t K = 300;
    const auto m = q_power_moments(mu1, mu2, K);
    const mpfr_real root = sqrt(mu1);
    const mpfr_real r = (1 - root) / (1 + root);
    for (std::size_t row = 0; row < 3; ++row) {
      const mpfr_real q0 = abs(m.Q[row][0]);
      mpfr_real r_k = 1;
      for (std::size_t k = 0; k < K; ++k) {
        INFO("mu1 = " << m1 << " row " << row << " k = " << k);
        // The computed Q_k carry relative_error * max |Q| of rounding: compare beyond it.
        CHECK(abs(m.Q[row][k]) <= (k + 1) * r_k * q0 + 2 * m.relative_error * q0);
        if (row == 1 && k > 0) {
          CHECK(m.Q[1][k] > 0);
          CHECK(m.Q[1][k] <= r * m.Q[1][k - 1] + 2 * m.relative_error * q0);
        }
        r_k *= r;
      }
    }
  }
}
