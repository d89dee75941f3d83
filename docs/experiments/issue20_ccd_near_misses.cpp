// Issue 20 experiment (docs/performance.md): for every false positive of `nexdyn ccd` on a query
// file, the smallest distance of the pair over [0, 1], sampled at 200,001 times in long double and
// refined by ternary search around the best sample. Not part of the build. From the repository
// root, after ./build.sh:
//   g++ -O2 -std=c++20 -I. -I/usr/include/eigen3 docs/experiments/issue20_ccd_near_misses.cpp \
//       build/engine/libnexdyn_engine.a build/kernels/libnexdyn_kernels.a -ltbb -o /tmp/near_misses
//   /tmp/near_misses tests/data/ccd/vertex-face.txt
#include "engine/ccd_queries.hpp"
#include "kernels/ccd/ccd.hpp"
#include "kernels/distance/point_triangle_distance.hpp"
#include <cstdio>
#include <cmath>
#include <Eigen/Core>
#include <Eigen/Geometry>
using namespace nexdyn;
using V=Eigen::Matrix<long double,3,1>;
static long double ps(const V&p,const V&a,const V&b){V ab=b-a,ap=p-a;long double l=ab.squaredNorm(),s=ap.dot(ab);if(s<=0||l==0)return ap.norm();if(s>=l)return (p-b).norm();return ap.cross(ab).norm()/std::sqrt(l);}
static long double pt(const V&p,const V&a,const V&b,const V&c){V n=(b-a).cross(c-a);long double wa=(b-p).cross(c-p).dot(n),wb=(c-p).cross(a-p).dot(n),wc=(a-p).cross(b-p).dot(n);
 if(n.squaredNorm()>0&&wa>=0&&wb>=0&&wc>=0)return std::abs((p-a).dot(n))/n.norm();return std::min({ps(p,a,b),ps(p,b,c),ps(p,c,a)});}
static long double ee(const V&a0,const V&a1,const V&b0,const V&b1){V da=a1-a0,db=b1-b0,w=b0-a0,n=da.cross(db);long double n2=n.squaredNorm();
 long double bd=std::min({ps(a0,b0,b1),ps(a1,b0,b1),ps(b0,a0,a1),ps(b1,a0,a1)});
 if(n2>0){long double s=w.cross(db).dot(n),t=w.cross(da).dot(n);if(s>=0&&s<=n2&&t>=0&&t<=n2)return std::min(bd,std::abs(w.dot(n))/std::sqrt(n2));}return bd;}
int main(int argc,char**argv){
 auto set=read_ccd_queries(argv[1]);
 for(int64_t i=0;i<set.size();++i){const double*q=set.points.data()+24*i;
  Eigen::Vector3d x[8];Eigen::Vector3d lo=Eigen::Vector3d::Constant(INFINITY),hi=-lo;
  for(int k=0;k<8;++k){x[k]=Eigen::Vector3d(q[3*k],q[3*k+1],q[3*k+2]);lo=lo.cwiseMin(x[k]);hi=hi.cwiseMax(x[k]);}
  double md=1e-11*(hi-lo).norm(),toi=1;
  bool r=ccd_query_collides(set.kind,q);
  if(!(r && !set.truth[i])) continue;
  // sampled min distance in long double
  long double best=1e30,bt=0; int N=200000;
  auto D=[&](long double t){V y[4];for(int k=0;k<4;++k){V a=x[k].cast<long double>(),b=x[k+4].cast<long double>();y[k]=a+t*(b-a);}
   return set.kind==CcdQueryKind::vertex_face? pt(y[0],y[1],y[2],y[3]):ee(y[0],y[1],y[2],y[3]);};
  for(int s=0;s<=N;++s){long double t=(long double)s/N,d=D(t);if(d<best){best=d;bt=t;}}
  // refine
  long double a=std::max(0.0L,bt-1.0L/N),b=std::min(1.0L,bt+1.0L/N);
  for(int it=0;it<200;++it){long double m1=a+(b-a)/3,m2=b-(b-a)/3;if(D(m1)<D(m2))b=m2;else a=m1;}
  long double dm=std::min(best,D((a+b)/2));
  printf("%lld toi=%.6g d0=%.3Le mind=%.3Le at t=%.6Lf diag=%.3g md=%.3g ratio=%.3Le\n",(long long)i,toi,D(0),dm,(a+b)/2,(hi-lo).norm(),md,dm/md);
 }}
